"""/logs in real headless Chromium: the server's request lines and warnings, filtered by level, text and count,
with hostile paths shown as text."""

from __future__ import annotations

import logging

import httpx
import pytest

from tests.conftest import UiStack
from tests.ui.conftest import axe_violations

pytestmark = pytest.mark.browser

HOSTILE_PATH = "/reports/<script>window.__pwned=1</script>"


def test_logs_page_lists_requests_and_filters_them(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    for n in range(3):
        httpx.get(f"{ui_stack.api_url}/healthz/live", headers={"X-Request-ID": f"probe-{n}"})
    httpx.get(ui_stack.api_url + HOSTILE_PATH.replace("<", "%3C").replace(">", "%3E"), headers={"X-Request-ID": "xss"})
    logging.getLogger("segb.store").warning("virtuoso does not answer (logs-page test)")

    page.goto(f"{ui_stack.ui_url}/logs")
    assert page.locator("h1").inner_text() == "Server log"
    assert page.locator("nav.sidebar a[aria-current=page]").inner_text() == "Logs"
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


def test_the_log_counts_its_entries_and_links_each_page(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    for n in range(153):
        httpx.get(f"{ui_stack.api_url}/healthz/live", headers={"X-Request-ID": f"counted-{n:03d}"})

    def ids() -> list[str]:  # each cell shows the first characters of its request id, its title the whole id
        return page.locator("#server-log tbody tr code.request-id").evaluate_all("ids => ids.map(id => id.title)")

    page.goto(f"{ui_stack.ui_url}/logs?contains=counted-")
    assert page.locator(".card-sub").inner_text() == "1\u201350 of 153, newest first"
    numbers = page.locator(".pager .page-numbers a")
    assert numbers.all_text_contents() == ["Page 1", "Page 2", "Page 3", "Page 4"]
    assert page.locator(".pager a[aria-current=page]").text_content() == "Page 1"
    assert page.evaluate("document.documentElement.scrollHeight") < 6000

    page.click(".pager .page-numbers a:has-text('Page 3')")
    page.wait_for_load_state()
    assert page.locator(".card-sub").inner_text() == "101\u2013150 of 153, newest first"
    assert ids() == [f"counted-{n:03d}" for n in range(52, 2, -1)]
    assert page.locator(".pager a[aria-current=page]").text_content() == "Page 3"
    assert axe_violations(page) == []
    page.click(".pager a:has-text('Older 50')")
    page.wait_for_load_state()
    assert page.locator(".card-sub").inner_text() == "151\u2013153 of 153, newest first"
    assert ids() == ["counted-002", "counted-001", "counted-000"]
    assert page.console_errors == []
