"""What an auditor reads on `segb serve --demo` once the example robot has run, in real headless Chromium: the
findings' "why?" on one line and the human each reply without the dialogue model answers; the people table padded,
with each person's erasure previewed from their row (two Marias told apart by their IRIs), nothing typed."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, words_split

pytestmark = pytest.mark.browser

MIRRORS_MARIA = "https://example.org/segb/robots/mirror/v1/human_maria"
REPLY_WITHOUT_MODEL = "Reply without the dialogue model"

# Each "why?" link: the lines its text takes (a word split over two lines has two boxes), its height and
# line height.
WHY_BOXES = """links => links.map(link => {
  const range = document.createRange();
  range.selectNodeContents(link.firstChild);
  return [range.getClientRects().length, link.getBoundingClientRect().height,
          parseFloat(getComputedStyle(link).lineHeight)];
})"""

# Words of the findings' cells drawn on more than one line (a finding's sentence, robot text, may break anywhere).
# Each cell's smallest padding, of its four sides.
SMALLEST_PADDING = """cells => cells.map(cell => {
  const style = getComputedStyle(cell);
  return Math.min(...["Top", "Right", "Bottom", "Left"].map(side => parseFloat(style["padding" + side])));
})"""


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_findings_keep_why_on_one_line_and_name_whom_a_reply_answers(
    demo_stack: UiStack, open_at: Any, viewport: str
) -> None:
    answer = httpx.get(f"{demo_stack.api_url}/findings", params={"rule": "reply-without-model"}, timeout=30).json()
    humans = {found["focus"]: found["human"] for found in answer["findings"]}
    assert len(humans) == 9 and all(humans.values())  # ARI's four replies, TIAGo's one, the example robot's four
    page = open_at(viewport)
    page.goto(f"{demo_stack.ui_url}/findings")
    boxes = page.locator("#findings-list a.explain-link").evaluate_all(WHY_BOXES)
    assert len(boxes) == 10
    assert all(lines == 1 and height <= 1.5 * line_height for lines, height, line_height in boxes), boxes
    replies = page.locator("#findings-list tr.finding", has_text=REPLY_WITHOUT_MODEL)
    assert replies.count() == 9
    for row in replies.all():
        human = row.locator("td").nth(4).locator(".entity")
        assert human.get_attribute("title") == humans[row.get_attribute("data-focus")]
        assert human.inner_text().split(" (")[0] in {"Maria", "Carlos"}
        assert f" to {human.inner_text().split(' (')[0]}: " in row.locator("td.message").inner_text()
    assert axe_violations(page) == []


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_no_word_of_a_rule_severity_or_name_is_split_on_the_findings_page(
    demo_stack: UiStack, open_at: Any, viewport: str
) -> None:
    """A title split as "Repl / y without the dialo / gue model" reads as badly as "wh / y?": on a phone the
    tables scroll sideways instead."""
    page = open_at(viewport)
    page.goto(f"{demo_stack.ui_url}/findings")
    assert page.locator("#findings-live tr.finding").count() > 0
    assert words_split(page, "#findings-live td:not(.message)") == []


def test_an_auditor_previews_a_persons_erasure_from_the_list(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/people")
    paddings = page.locator("#people td, #people th").evaluate_all(SMALLEST_PADDING)
    assert paddings and min(paddings) > 0
    assert page.locator("#people tbody tr", has_text="Maria").count() == 2  # namesakes, told apart by their IRIs
    row = page.locator("#people tbody tr", has_text=MIRRORS_MARIA)
    row.get_by_role("button", name="Preview erasure").click()
    page.wait_for_load_state()
    assert MIRRORS_MARIA in page.locator("#erase-preview h2").inner_text()
    assert "nothing has been erased" in page.locator("#erase-preview").inner_text()
    assert page.locator("#erase-iri").input_value() == MIRRORS_MARIA  # the form below is filled in for her
    assert page.locator("#erase-confirm").input_value() == ""  # erasing still takes the typed confirmation
    assert page.locator("#erase-form input[name=csrf_token]").input_value()
    assert axe_violations(page) == []
    assert page.console_errors == []
