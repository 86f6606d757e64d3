"""Time filters take and show ISO 8601 UTC, as the tables show times: the timeline's window typed in real Chromium
comes back in ISO and narrows the events, and a value that is no time is refused by the page with a message that
says which filter and how to write it."""

from __future__ import annotations

import html
from typing import Any

import httpx
import pytest

from segb_server.ui.query_params import iso_time
from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, visit

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
EXAMPLE = "2026-03-10T09:00:00Z"
PAGES = ["/timeline?" + str(httpx.QueryParams({"robot": ARI})), "/findings?", "/reports/emotion-timeline?", "/reports?"]


@pytest.mark.browser
def test_the_timeline_window_comes_back_in_iso_and_narrows_the_events(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/timeline?{httpx.QueryParams({'robot': ARI})}")
    every = page.locator(".tl-shown").inner_text()
    for name in ("since", "until"):
        field = page.locator(f"form.filters input[name={name}]")
        assert field.get_attribute("type") == "text" and field.get_attribute("placeholder") == EXAMPLE
    page.fill("form.filters input[name=since]", "2026-03-10 10:00:20")  # as the list shows times
    page.fill("form.filters input[name=until]", "2026-03-10T10:00:31Z")
    page.click("form.filters button[type=submit]")
    page.wait_for_selector("#timeline-progress:has-text('events in this window')")
    assert page.locator("form.filters input[name=since]").input_value() == "2026-03-10T10:00:20Z"
    assert page.locator("form.filters input[name=until]").input_value() == "2026-03-10T10:00:31Z"
    shown = page.locator(".tl-shown").inner_text()
    assert shown != every and not shown.startswith("0 ")
    times = page.locator(".tl-row:not([hidden]) .tl-time").all_inner_texts()  # a window of one day: no date
    assert times and all("10:00:20" <= time[:8] <= "10:00:31" for time in times), times
    assert axe_violations(page) == []
    assert page.console_errors == []


@pytest.mark.parametrize("path", PAGES)
@pytest.mark.parametrize("typed", ["yesterday", "03/10/2026, 09:00:00 AM", "2026-13-45T09:00:00Z"])
def test_a_value_that_is_no_time_is_refused_with_what_to_type(ui_stack: UiStack, path: str, typed: str) -> None:
    answer = httpx.get(f"{ui_stack.ui_url}{path}&{httpx.QueryParams({'since': typed})}", timeout=30)
    assert answer.status_code == 422
    message = html.unescape(answer.text.split('class="banner banner-error"')[1].split("</p>")[0])
    assert "Since (UTC)" in message and EXAMPLE in message
    assert f"\u201c{typed}\u201d" in message  # as it was typed, nothing added


@pytest.mark.parametrize(
    ("typed", "sent"),
    [
        (EXAMPLE, EXAMPLE),
        ("2026-03-10 09:00:00", EXAMPLE),  # as the tables show times
        ("2026-03-10T09:00", "2026-03-10T09:00Z"),
        ("2026-03-10T09:00:00.250+01:00", "2026-03-10T09:00:00.250+01:00"),
    ],
)
def test_a_time_is_sent_in_iso_utc_unless_it_names_its_zone(typed: str, sent: str) -> None:
    assert iso_time("since", typed) == sent
