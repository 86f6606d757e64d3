"""The session page: paste a token, an HttpOnly SameSite=Strict cookie, role-aware navigation, sign-out, CSRF."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from segb_server.backend.auth import mint_token
from tests.conftest import UiStack, start_ui_stack

SECRET = "k" * 40
pytestmark = pytest.mark.browser


@pytest.fixture
def secured_stack(memory_store) -> Iterator[UiStack]:  # type: ignore[no-untyped-def]
    yield from start_ui_stack(memory_store, secret_key=SECRET)


def token_for(*roles: str, username: str = "auditor-ann", expires_in: int = 600) -> str:
    return mint_token(SECRET, username=username, roles=roles, expires_in=expires_in).token


def test_pasting_a_token_signs_in_and_the_nav_follows_the_roles(secured_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{secured_stack.ui_url}/session")
    assert page.locator(".session-pill").inner_text() == "No token"
    page.fill("#token", token_for("auditor"))
    page.click("text=Save token")

    assert page.locator("#session-user").inner_text() == "auditor-ann"
    assert page.locator(".banner-success").inner_text() == "Token saved for this browser session."
    nav = page.locator("nav.sidebar").inner_text()
    assert "Reports" in nav and "Ledger" in nav
    assert "Logs" not in nav and "Shared context" not in nav  # admin pages are hidden from an auditor
    cookie = next(c for c in page.context.cookies() if c["name"] == "segb_token")
    assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"
    assert page.evaluate("document.cookie").find("segb_token") == -1

    page.click("text=Sign out")
    assert page.locator(".session-pill").inner_text() == "No token"
    assert all(c["name"] != "segb_token" for c in page.context.cookies())
    assert page.console_errors == []


def test_a_rejected_token_is_explained(secured_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{secured_stack.ui_url}/session")
    page.fill("#token", token_for("auditor")[:-4] + "AAAA")
    page.click("text=Save token")
    assert "The API refused this token: Could not validate credentials. Invalid Token" in page.inner_text("main")
    assert all(c["name"] != "segb_token" for c in page.context.cookies())


def test_an_expired_token_in_the_cookie_is_flagged(secured_stack: UiStack) -> None:
    expired = mint_token(SECRET, username="old", roles=["admin"], expires_in=60, now=1_000_000).token
    answer = httpx.get(f"{secured_stack.ui_url}/session", cookies={"segb_token": expired})
    assert "Token rejected" in answer.text
    assert "Expired Token" in answer.text


def test_forms_without_the_csrf_token_are_refused(secured_stack: UiStack) -> None:
    with httpx.Client(base_url=secured_stack.ui_url) as client:
        client.get("/session")  # receives the CSRF cookie
        forged = client.post("/session", data={"token": token_for("admin")})
        assert forged.status_code == 403
        assert "security token" in forged.text
        assert "segb_token" not in forged.headers.get("set-cookie", "")
        # A form refused is no question of roles: the page does not send its user to look at the token's.
        assert "does not carry the role" not in forged.text


def test_with_auth_off_the_page_says_so(ui_stack: UiStack) -> None:
    answer = httpx.get(f"{ui_stack.ui_url}/session")
    assert "Authentication off" in answer.text
    assert 'name="token"' not in answer.text


def test_the_session_shows_what_the_token_grants(secured_stack: UiStack, page: Any) -> None:
    minted = mint_token(SECRET, username="ops", roles=["admin"], expires_in=600, scopes=["https://example.org/ari/"])
    page.goto(f"{secured_stack.ui_url}/session")
    page.fill("#token", minted.token)
    page.click("text=Save token")
    assert page.locator("#session-user").inner_text() == "ops"
    assert page.locator("#session-token-roles").inner_text().split() == ["admin"]
    assert set(page.locator("#session-roles").inner_text().split()) == {"admin", "auditor", "logger"}
    assert page.locator("#session-scopes").inner_text() == "https://example.org/ari/"
    expires = time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(minted.expires_at))
    assert page.locator("#session-expires").inner_text() == expires


def test_a_page_needing_a_token_says_how_to_get_one_and_signing_in_leads_back(
    secured_stack: UiStack, page: Any
) -> None:
    answer = page.goto(f"{secured_stack.ui_url}/reports/participants?limit=5")
    assert answer is not None and answer.status == 401
    main = page.locator("main").inner_text()
    assert "this browser has no token yet" in main
    assert "segb token --username NAME --role auditor" in main
    assert "Authorization header is required" not in page.locator(".banner").inner_text()

    page.click("#sign-in-help a")
    assert "The page you opened needs a token" in page.locator(".banner-info").inner_text()
    page.fill("#token", token_for("auditor"))
    page.click("text=Save token")
    page.wait_for_load_state()
    assert page.url == f"{secured_stack.ui_url}/reports/participants?limit=5"
    assert page.locator("h1").inner_text() == "Participants"


def test_signing_in_never_leads_off_the_site(secured_stack: UiStack) -> None:
    with httpx.Client(base_url=secured_stack.ui_url) as client:
        client.get("/session")
        csrf = client.cookies["segb_csrf"]
        for elsewhere in ("https://evil.example/", "//evil.example/", "/\\evil.example"):
            answer = client.post(
                "/session", data={"token": token_for("auditor"), "csrf_token": csrf, "next": elsewhere}
            )
            assert answer.status_code == 303
            assert answer.headers["location"] == "/session?notice=saved"
