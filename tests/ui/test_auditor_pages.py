"""What an auditor reads, in real headless Chromium: the findings' "why?" on one line, the server log in pages
with a message column that does not repeat the others, counts in words that fit them (one receipt; snapshots and
the rows they are made of), and time filters that take and show ISO 8601 UTC times as the tables do. axe-core
finds nothing serious on any of these pages."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from tests.conftest import UiStack
from tests.support.rule_scenarios import troubled
from tests.support.settle import settle
from tests.ui.conftest import VIEWPORTS, axe_violations, run_example_robot

pytestmark = pytest.mark.browser

ISO_PLACEHOLDER = "2026-03-10T09:00:00Z"

# Lines an element's first text takes: a word split over two lines has two boxes.
TEXT_LINES = """element => {
  const range = document.createRange();
  range.selectNodeContents(element.firstChild);
  return range.getClientRects().length;
}"""
# The width a field's placeholder needs, against the room its box leaves for text.
PLACEHOLDER_ROOM = """field => {
  const style = getComputedStyle(field);
  const context = document.createElement("canvas").getContext("2d");
  context.font = style.font;
  const room = field.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight);
  return [context.measureText(field.placeholder).width, room];
}"""


@pytest.fixture
def open_page(browser: Any) -> Iterator[Any]:
    """`open_page("phone")` → a fresh page of that viewport size."""
    contexts: list[Any] = []

    def opener(viewport: str) -> Any:
        width, height = VIEWPORTS[viewport]
        contexts.append(browser.new_context(viewport={"width": width, "height": height}))
        return contexts[-1].new_page()

    yield opener
    for context in contexts:
        context.close()


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_why_stays_on_one_line_in_every_finding_row(ui_stack: UiStack, open_page: Any, viewport: str) -> None:
    troubled()[0].publish_all(ui_stack.api_url)
    page = open_page(viewport)
    page.goto(f"{ui_stack.ui_url}/findings")
    links = page.locator("#findings-list a.explain-link")
    assert links.count() > 5
    assert set(links.evaluate_all(f"links => links.map({TEXT_LINES})")) == {1}
    line_height = page.evaluate("parseFloat(getComputedStyle(document.querySelector('a.explain-link')).lineHeight)")
    assert all(box["height"] < 1.5 * line_height for box in (link.bounding_box() for link in links.all()))
    assert axe_violations(page) == []


def test_the_server_log_comes_in_pages_and_its_message_adds_to_the_columns(ui_stack: UiStack, page: Any) -> None:
    for n in range(120):
        httpx.get(f"{ui_stack.api_url}/healthz/live", headers={"X-Request-ID": f"paged-{n:03d}"})
    ids = "#server-log tbody tr code.request-id"

    page.goto(f"{ui_stack.ui_url}/logs")
    assert page.locator("#server-log tbody tr").count() == 50
    assert page.evaluate("document.documentElement.scrollHeight") < 6000  # one screenful of pages, not 15,000 px
    probe = page.locator("#server-log tbody tr", has_text="paged-119")
    message = probe.locator("td.log-message").inner_text()
    assert "method=" not in message and "/healthz/live" not in message and "200" not in message
    assert message.startswith("from 127.0.0.1")  # what no other column shows
    assert axe_violations(page) == []

    page.goto(f"{ui_stack.ui_url}/logs?contains=paged-")
    first = page.locator(ids).all_inner_texts()
    assert first == [f"paged-{n:03d}" for n in range(119, 69, -1)]
    assert page.locator(".pager a", has_text="Newer").count() == 0
    page.click(".pager a:has-text('Older 50')")
    page.wait_for_load_state()
    assert page.locator(ids).all_inner_texts() == [f"paged-{n:03d}" for n in range(69, 19, -1)]
    assert page.locator("input[name=contains]").input_value() == "paged-"  # the filter is kept from page to page
    page.click(".pager a:has-text('Older 50')")
    page.wait_for_load_state()
    assert page.locator(ids).all_inner_texts() == [f"paged-{n:03d}" for n in range(19, -1, -1)]
    assert page.locator(".pager a", has_text="Older").count() == 0
    page.click(".pager a:has-text('Newer 50')")
    page.wait_for_load_state()
    assert page.locator(ids).first.inner_text() == "paged-069"
    assert axe_violations(page) == []


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_the_log_search_shows_its_whole_placeholder(ui_stack: UiStack, open_page: Any, viewport: str) -> None:
    page = open_page(viewport)
    page.goto(f"{ui_stack.ui_url}/logs")
    needed, room = page.locator("input[name=contains]").evaluate(PLACEHOLDER_ROOM)
    assert needed <= room, (needed, room)


def test_the_ledger_says_one_receipt(ui_stack: UiStack, page: Any) -> None:
    turtle = "<https://example.org/r> a <http://kb.openrobots.org#Robot> ."
    posted = httpx.post(f"{ui_stack.api_url}/ttl", content=turtle, headers={"Content-Type": "text/turtle"})
    assert posted.status_code == 201, posted.text
    page.goto(f"{ui_stack.ui_url}/ledger")
    assert page.locator(".banner-success").inner_text() == "Chain intact: 1 receipt"
    assert axe_violations(page) == []


def test_robot_states_count_snapshots_and_the_rows_they_are_made_of(ui_stack: UiStack, page: Any) -> None:
    run_example_robot(ui_stack.api_url)  # one state snapshot per reply (4), each several properties
    settle(ui_stack.api_url)
    rows = httpx.get(f"{ui_stack.api_url}/reports/robot-states", timeout=30).json()["rows"]
    page.goto(f"{ui_stack.ui_url}/reports/robot-states")
    assert page.locator("#report-robot-states tbody tr").count() == 4
    assert page.locator("#report-count").inner_text() == (
        f"4 snapshots, made of rows 1\u2013{len(rows)} (one row per property)"
    )
    assert axe_violations(page) == []


def time_field(page: Any, name: str) -> Any:
    return page.locator(f"form.filters input[name={name}]")


@pytest.mark.parametrize("path", ["/findings", "/reports/emotion-timeline", "/timeline", "/kg-graph"])
def test_every_time_filter_takes_and_shows_iso_utc(ui_stack: UiStack, page: Any, path: str) -> None:
    page.goto(f"{ui_stack.ui_url}{path}")
    for name in ("since", "until"):
        field = time_field(page, name)
        assert field.get_attribute("type") == "text"  # no picker showing the viewer's locale, mm/dd/yyyy
        assert field.get_attribute("placeholder") == ISO_PLACEHOLDER
        assert "(UTC)" in field.locator("xpath=..").inner_text()  # its label
        needed, room = field.evaluate(PLACEHOLDER_ROOM)
        assert needed <= room, (path, needed, room)
    since = time_field(page, "since")
    for accepted in (ISO_PLACEHOLDER, "2026-03-10 09:00:00", "2026-03-10T09:00", "2026-03-10T09:00:00.250+01:00"):
        since.fill(accepted)
        assert since.evaluate("field => field.checkValidity()"), accepted
    for refused in ("03/10/2026, 09:00:00 AM", "yesterday", "2026-03-10"):
        since.fill(refused)
        assert not since.evaluate("field => field.checkValidity()"), refused


def test_a_time_typed_as_the_tables_show_it_filters_and_comes_back_in_iso(ui_stack: UiStack, page: Any) -> None:
    troubled()[0].publish_all(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/findings")
    # `2026-03-10 09:00:05`; a finding about a node with no time (a missing type) has none.
    times = [shown for shown in page.locator("#findings-list td.time").all_inner_texts() if shown]
    assert len(set(times)) > 2
    middle = sorted(times)[len(times) // 2]
    time_field(page, "since").fill(middle)  # pasted from the table
    page.click("form.filters button[type=submit]")
    page.wait_for_load_state()
    assert time_field(page, "since").input_value() == middle.replace(" ", "T") + "Z"
    kept = [shown for shown in page.locator("#findings-list td.time").all_inner_texts() if shown]
    assert kept and all(shown >= middle for shown in kept) and len(kept) < len(times)
    assert axe_violations(page) == []
