"""/logs in real headless Chromium: the server's request lines and warnings, filtered by level, text and count,
with hostile paths shown as text."""

from __future__ import annotations

import logging

import httpx
import pytest

from tests.conftest import UiStack

pytestmark = pytest.mark.browser

HOSTILE_PATH = "/reports/<script>window.__pwned=1</script>"


def test_logs_page_lists_requests_and_filters_them(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    for n in range(3):
        httpx.get(f"{ui_stack.api_url}/healthz/live", headers={"X-Request-ID": f"probe-{n}"})
    httpx.get(ui_stack.api_url + HOSTILE_PATH.replace("<", "%3C").replace(">", "%3E"), headers={"X-Request-ID": "xss"})
    logging.getLogger("segb.store").warning("virtuoso does not answer (logs-page test)")

    page.goto(f"{ui_stack.ui_url}/logs")
    assert page.locator("h1").inner_text() == "Server log"
    assert page.locator("nav a[aria-current=page]").inner_text() == "Logs"
    rows = page.locator("#server-log tbody tr")
    levels = set(rows.evaluate_all("rows => rows.map(r => r.dataset.level)"))
    assert levels == {"INFO", "WARNING"}
    probe = page.locator("#server-log tbody tr", has_text="probe-2")
    assert probe.locator("td.log-route").inner_text() == "GET /healthz/live"
    assert probe.locator("td").nth(5).inner_text() == "200"
    assert "segb.requests" in probe.locator("td.log-level").inner_text()  # the logger, under the level
    hostile = page.locator("#server-log tbody tr", has_text="xss")
    assert hostile.locator("td.log-route").inner_text() == f"GET {HOSTILE_PATH}"
    assert page.evaluate("window.__pwned") is None

    page.select_option("select[name=level]", "WARNING")
    page.click("#log-filters button[type=submit]")
    page.wait_for_load_state()
    assert "level=WARNING" in page.url
    warnings = page.locator("#server-log tbody tr")
    assert set(warnings.evaluate_all("rows => rows.map(r => r.dataset.level)")) == {"WARNING"}
    assert "virtuoso does not answer (logs-page test)" in warnings.first.inner_text()

    page.select_option("select[name=level]", "INFO")
    page.fill("input[name=contains]", "PROBE-")
    page.fill("input[name=limit]", "2")
    page.click("#log-filters button[type=submit]")
    page.wait_for_load_state()
    shown = page.locator("#server-log tbody tr code.request-id").all_inner_texts()
    assert shown == ["probe-2", "probe-1"]
    assert page.locator("input[name=contains]").input_value() == "PROBE-"
    assert page.console_errors == []


def test_a_page_size_past_the_largest_shows_the_largest(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_stack.ui_url}/logs?limit=5000")
    assert page.locator("input[name=limit]").input_value() == "500"


def test_a_page_further_than_the_log_is_read_back_is_explained(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_stack.ui_url}/logs?offset=5000")
    assert "offset" in page.locator(".banner-error").inner_text()
