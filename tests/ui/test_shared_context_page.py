"""/shared-context in real headless Chromium: a review side by side, accept and reject forms, CSRF, roles."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

import httpx
import pytest

from segb_server.backend.auth import mint_token
from tests.conftest import UiStack, start_ui_stack

pytestmark = pytest.mark.browser

SECRET = "s" * 40
AT = datetime(2026, 5, 4, 10, 0, 0, tzinfo=UTC)
HOSTILE = '<script>window.__pwned = 1</script><img src=x onerror="window.__pwned = 2">'


def resolve(api_url: str, seconds: float, subject: str | None, text: str, headers: dict[str, str] | None = None) -> str:
    body: dict[str, Any] = {
        "event_kind": "human_utterance",
        "observed_at": (AT + timedelta(seconds=seconds)).isoformat(),
        "subject_uri": subject,
        "modality": "speech",
        "text": text,
        "robot_uri": "https://example.org/robots/ari",
    }
    answer = httpx.post(f"{api_url}/shared-context/resolve", json=body, headers=headers or {}, timeout=10)
    assert answer.status_code == 200, answer.text
    return answer.json()["shared_context_uri"]


def one_review(
    api_url: str, text: str = "Good morning, robot!", headers: dict[str, str] | None = None
) -> tuple[str, str]:
    """A matched context and an ambiguous one next to it (no subject, half a second later)."""
    target = resolve(api_url, 0, "https://example.org/people/maria", text, headers)
    source = resolve(api_url, 0.5, None, text, headers)
    return source, target


def test_a_review_shows_both_contexts_and_accepting_merges_them(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    source, target = one_review(ui_stack.api_url, text=HOSTILE)

    page.goto(f"{ui_stack.ui_url}/shared-context")
    assert page.locator("nav a[aria-current=page]").inner_text() == "Shared context"
    review = page.locator(".review")
    assert review.count() == 1
    assert review.locator(".context-source").get_attribute("data-uri") == source
    assert review.locator(".context-candidate").get_attribute("data-uri") == target
    assert "maria" in review.locator(".context-candidate").inner_text()
    assert HOSTILE in review.locator(".context-source .observation-text").inner_text()
    assert page.evaluate("window.__pwned") is None
    assert "Score 0.84" in review.inner_text()

    page.click("button.accept")
    assert page.locator(".banner-success").inner_text().startswith("Merged")
    assert page.locator("#no-reviews").is_visible()
    assert "1 active · 0 ambiguous · 1 merged" in page.locator("#shared-context-stats").inner_text()
    assert page.console_errors == []


def test_rejecting_keeps_the_context_apart(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    source, _ = one_review(ui_stack.api_url)

    page.goto(f"{ui_stack.ui_url}/shared-context")
    page.click("button.reject")
    assert page.locator(".banner-success").inner_text().startswith("Rejected")
    assert page.locator(".review").count() == 0
    assert page.locator(f".context[data-uri='{source}']").count() == 1  # listed as ambiguous without a case
    assert "1 active · 1 ambiguous · 0 merged · 0 waiting" in page.locator("#shared-context-stats").inner_text()


def test_decisions_without_the_csrf_token_are_refused(ui_stack: UiStack) -> None:
    one_review(ui_stack.api_url)
    case_id = httpx.get(f"{ui_stack.api_url}/shared-context/review/pending", timeout=10).json()["pending_cases"][0][
        "case_id"
    ]
    forged = httpx.post(
        f"{ui_stack.ui_url}/shared-context/review/{case_id}/reject", data={"csrf_token": "forged"}, timeout=10
    )
    assert forged.status_code == 403
    assert httpx.get(f"{ui_stack.api_url}/shared-context/stats", timeout=10).json()["pending_cases"] == 1


@pytest.fixture
def secured_stack(memory_store) -> Iterator[UiStack]:  # type: ignore[no-untyped-def]
    yield from start_ui_stack(memory_store, secret_key=SECRET)


def sign_in(page, ui_url: str, *roles: str) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_url}/session")
    page.fill("#token", mint_token(SECRET, username="someone", roles=roles, expires_in=600).token)
    page.click("text=Save token")


def test_only_admins_reach_the_review_page(secured_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    logger = {"Authorization": "Bearer " + mint_token(SECRET, username="ari", roles=["logger"], expires_in=600).token}
    one_review(secured_stack.api_url, headers=logger)

    sign_in(page, secured_stack.ui_url, "auditor")
    assert "Shared context" not in page.locator("nav.sidebar").inner_text()
    answer = page.goto(f"{secured_stack.ui_url}/shared-context")
    assert answer is not None and answer.status == 403
    assert page.locator(".review").count() == 0

    sign_in(page, secured_stack.ui_url, "admin")
    page.goto(f"{secured_stack.ui_url}/shared-context")
    assert page.locator(".review").count() == 1
    assert "via ari" in page.locator(".context-source").inner_text()


def test_the_demo_gives_the_page_contexts_and_a_case_to_review(demo_stack: UiStack, open_at: Any) -> None:
    """The demo's robots resolve their utterances with the server, so the page counts what the graph shows,
    and the two robots' `human_maria` subjects are told apart."""
    stats = httpx.get(f"{demo_stack.api_url}/shared-context/stats", timeout=10).json()
    assert stats["active_contexts"] >= 5 and stats["ambiguous_contexts"] >= 1 and stats["pending_cases"] >= 1
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/shared-context")
    shown = page.locator("#shared-context-stats").inner_text()
    assert shown.startswith(f"{stats['active_contexts']} active · {stats['ambiguous_contexts']} ambiguous")
    assert page.locator(".review").count() == stats["pending_cases"]
    # TIAGo overheard Maria without seeing who spoke: a context without subject, beside ARI's.
    sources = page.locator(".context-source dl").all_inner_texts()
    assert sum("Subject\nnone\n" in source for source in sources) == 1
    subjects = page.locator(".context dd .entity").all_inner_texts()
    assert "Maria (ARI, TIAGo)" in subjects and "Maria (Emotion Mirror)" in subjects
