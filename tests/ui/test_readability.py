"""Pages read well at a glance, at 1440x900 and 390x844 in Chromium: nothing wider than the screen unless it
scrolls inside a visible scroll area, no header split inside a word, every row a report page counts on the
page (on screen and in print), chart labels inside their charts, the server log fitting a desktop screen."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.conftest import UiStack
from tests.ui.conftest import REPORTS, demo_pages, screenshot, visit, words_split

pytestmark = pytest.mark.browser

# Elements sticking out of the viewport, unless a visible box that scrolls sideways holds them.
OVERFLOWING = """() => {
  const width = document.documentElement.clientWidth, out = [];
  if (document.documentElement.scrollWidth > width) out.push(`page ${document.documentElement.scrollWidth}px`);
  const scroller = el => {
    for (let p = el.parentElement; p; p = p.parentElement) {
      const style = getComputedStyle(p);
      if (["auto", "scroll"].includes(style.overflowX)) return p;
    }
    return null;
  };
  for (const el of document.querySelectorAll("#content *")) {
    const box = el.getBoundingClientRect();
    if (box.width === 0 || box.right <= width + 1) continue;
    const area = scroller(el);
    const held = area && area.getBoundingClientRect().right <= width + 1 && area.getBoundingClientRect().width > 0
      && area.scrollWidth > area.clientWidth;
    if (!held) out.push(`${el.tagName.toLowerCase()}.${el.className} ends at ${Math.round(box.right)}px`);
  }
  return out.slice(0, 10);
}"""

# Header words drawn on more than one line.
# Listed rows hidden by a box that scrolls up and down (or clips) instead of growing.
CLIPPED_ROWS = """() => [...document.querySelectorAll("#content tbody tr")].filter(row => {
  const box = row.getBoundingClientRect();
  for (let p = row.parentElement; p; p = p.parentElement) {
    const style = getComputedStyle(p);
    if (style.overflowY !== "visible" && p.scrollHeight > p.clientHeight + 1) return true;
    const outer = p.getBoundingClientRect();
    if (style.overflowY !== "visible" && (box.bottom > outer.bottom + 1 || box.top < outer.top - 1)) return true;
  }
  return false;
}).length"""


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_no_page_is_wider_than_the_screen(demo_stack: UiStack, open_at: Any, viewport: str) -> None:
    page = open_at(viewport)
    found = {}
    for path, name in demo_pages(demo_stack).items():
        visit(page, demo_stack.ui_url + path)
        sticking_out = page.evaluate(OVERFLOWING)
        if sticking_out:
            found[path] = sticking_out
            screenshot(page, f"wide-{viewport}-{name}")
    assert found == {}


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_no_table_header_breaks_inside_a_word(demo_stack: UiStack, open_at: Any, viewport: str) -> None:
    page = open_at(viewport)
    found = {}
    for path in demo_pages(demo_stack):
        visit(page, demo_stack.ui_url + path)
        split = words_split(page, "th")
        if split:
            found[path] = split
    assert found == {}


def test_the_header_check_finds_a_split_word(demo_stack: UiStack, open_at: Any) -> None:
    """The check above can fail: headers allowed to break anywhere, in columns squeezed narrow."""
    page = open_at("phone")
    page.goto(f"{demo_stack.ui_url}/reports/ml-usage")
    page.evaluate("""() => {
      document.querySelectorAll("table.data").forEach(t => { t.style.minWidth = "0"; t.style.width = "300px"; });
      document.querySelectorAll("th").forEach(th => { th.style.overflowWrap = "anywhere"; });
    }""")
    assert words_split(page, "th")


@pytest.mark.parametrize("media", ["screen", "print"])
def test_a_single_report_page_shows_every_row_it_counts(demo_stack: UiStack, open_at: Any, media: str) -> None:
    page = open_at("desktop")
    page.emulate_media(media=media)
    for name in REPORTS:
        page.goto(f"{demo_stack.ui_url}/reports/{name}")
        count = page.locator("#report-count").inner_text()
        if name == "conversations":
            listed = page.locator(".bubble").count()
        else:
            listed = page.locator(f"#report-{name} tbody tr").count()
        counted = re.match(r"(?:\w+ 1\u2013(\d+)$|(\d+) \w+, made of rows 1\u2013\d+ \(one row per property\)$)", count)
        assert counted is not None, count
        assert int(counted.group(1) or counted.group(2)) == listed > 0, (name, count)
        assert page.evaluate(CLIPPED_ROWS) == 0, name


def test_robot_states_counts_snapshots_not_property_rows(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports/robot-states")
    snapshots = page.locator("#report-robot-states tbody tr")
    # ARI and the example robot: one per reply (4 each); TIAGo: Carlos's reply and the docking.
    assert snapshots.count() == 10
    assert re.fullmatch(
        r"10 snapshots, made of rows 1\u2013\d+ \(one row per property\)", page.locator("#report-count").inner_text()
    )
    assert "docking" in snapshots.last.inner_text()  # the last one, TIAGo's, is on the page


def test_the_overview_lists_a_preview_and_says_so(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports")
    timeline = page.locator("#report-emotion-timeline")
    assert timeline.locator("tbody tr").count() == 10
    more = " ".join(timeline.locator("p.more").text_content().split())
    assert re.fullmatch(r"Listing 10 of \d+ rows\. Open the full report: Emotion timeline\.", more)
    assert page.evaluate(CLIPPED_ROWS) == 0


def test_chart_time_labels_stay_inside_their_charts(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports/emotion-timeline")
    outside = page.evaluate("""() => [...document.querySelectorAll("svg.emotion-chart")].flatMap(svg => {
      const chart = svg.closest("figure").getBoundingClientRect();
      return [...svg.querySelectorAll("text")].filter(t => {
        const box = t.getBoundingClientRect();
        return box.left < chart.left || box.right > chart.right;
      }).map(t => t.textContent);
    })""")
    assert outside == []
    last = page.locator("svg.emotion-chart").first.locator("text").last.text_content()
    assert re.fullmatch(r"\d\d:\d\d:\d\d(\.\d{3})?", last)  # a whole time, e.g. 10:00:32.500


def test_the_server_log_fits_a_desktop_screen(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/logs")
    widths = page.evaluate("""() => { const table = document.getElementById("server-log");
      return [table.getBoundingClientRect().width, table.parentElement.clientWidth]; }""")
    assert widths[0] <= widths[1] + 1
    headers = page.locator("#server-log thead th").all_inner_texts()
    assert headers[-2:] == ["Triples", "Message"]
    triples = page.locator("#server-log thead th", has_text="Triples")
    assert triples.bounding_box()["x"] + triples.bounding_box()["width"] <= 1440
    region = page.locator(".table-scroll").first
    assert region.get_attribute("tabindex") == "0" and region.get_attribute("role") == "region"
