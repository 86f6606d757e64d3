"""The UI shell in a real browser: navigation, health page, error pages, security headers."""

from __future__ import annotations

import httpx
import pytest

from tests.conftest import UiStack

pytestmark = pytest.mark.browser


def test_health_page_shows_the_probes_without_a_click(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_stack.ui_url}/health")
    assert page.locator("h1").inner_text() == "Backend health"
    assert page.get_by_text("Responding").is_visible()
    assert page.get_by_text("Connected").is_visible()
    assert page.locator("nav a[aria-current=page]").inner_text() == "Health"
    assert page.console_errors == []


def test_unknown_pages_get_an_html_error_page_not_a_traceback(ui_stack: UiStack) -> None:
    answer = httpx.get(f"{ui_stack.ui_url}/no-such-page")
    assert answer.status_code == 404
    assert "Page not found" in answer.text
    assert "Traceback" not in answer.text
    assert "default-src 'self'" in answer.headers["content-security-policy"]


def test_health_page_reports_an_unreachable_api(memory_store) -> None:  # type: ignore[no-untyped-def]
    from segb_server.ui.app import create_ui_app
    from tests.conftest import make_settings
    from tests.support.live_server import LiveServer
    from tests.support.net import free_port

    with LiveServer(create_ui_app(make_settings(backend_url=f"http://127.0.0.1:{free_port()}"))) as ui:
        answer = httpx.get(f"{ui.url}/health")
    assert answer.status_code == 200
    assert "does not answer" in answer.text
