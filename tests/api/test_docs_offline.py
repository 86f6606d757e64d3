"""The interactive API documentation works on a network without internet: its assets are served locally."""

from __future__ import annotations

import pytest

from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer

pytestmark = pytest.mark.browser


def block_the_internet(page) -> list[str]:  # type: ignore[no-untyped-def]
    """Abort every request that leaves the loopback interface; returns the URLs that tried."""
    tried: list[str] = []

    def route(route) -> None:  # type: ignore[no-untyped-def]
        host = route.request.url.split("/")[2].split(":")[0] if "://" in route.request.url else ""
        if route.request.url.startswith(("data:", "blob:")) or host in ("127.0.0.1", "localhost"):
            route.continue_()
        else:
            tried.append(route.request.url)
            route.abort()

    page.route("**/*", route)
    return tried


def test_swagger_ui_lists_the_operations_with_the_internet_blocked(live_api: LiveServer, page) -> None:  # type: ignore[no-untyped-def]
    tried = block_the_internet(page)
    page.goto(f"{live_api.url}/docs")
    page.wait_for_selector(".opblock-summary-path", timeout=20_000)
    paths = page.locator(".opblock-summary-path").all_inner_texts()
    assert "/ttl" in paths and "/reports/participants" in paths and "/healthz/ready" in paths
    assert tried == []
    assert page.console_errors == []


def test_redoc_renders_the_reference_with_the_internet_blocked(live_api: LiveServer, page) -> None:  # type: ignore[no-untyped-def]
    tried = block_the_internet(page)
    page.goto(f"{live_api.url}/redoc")
    page.wait_for_selector("h2:has-text('Publish RDF')", timeout=20_000)
    assert tried == []


def test_documentation_pages_forbid_inline_and_foreign_scripts(memory_api: InProcess) -> None:
    for path in ("/docs", "/redoc"):
        answer = memory_api.get(path)
        assert answer.status_code == 200
        policy = answer.headers["content-security-policy"]
        assert "script-src 'self';" in policy and "default-src 'none'" in policy
        assert "<script>" not in answer.text  # every script is a file: no inline code for the policy to allow
        assert "http" not in answer.text.split("<body>")[0].replace("http-equiv", "")  # no CDN in the head
