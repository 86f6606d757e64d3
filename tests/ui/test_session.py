"""The session page: paste a token, an HttpOnly SameSite=Strict cookie, role-aware navigation, sign-out, CSRF."""

from __future__ import annotations

from collections.abc import Iterator

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


def test_with_auth_off_the_page_says_so(ui_stack: UiStack) -> None:
    answer = httpx.get(f"{ui_stack.ui_url}/session")
    assert "Authentication off" in answer.text
    assert 'name="token"' not in answer.text
