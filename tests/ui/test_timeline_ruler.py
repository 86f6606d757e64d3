"""The timeline's ruler in real Chromium spreads a conversation over its width when the window holds long stretches
without events (a training run weeks before it, a window of months around it), and still shows the lone event
apart, labelled with its date, where a reader can see it."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, visit

pytestmark = pytest.mark.browser

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"  # trained on 2026-02-02, talks on 2026-03-10 for 33 s
WINDOWS = {
    # three quiet stretches of about the same length: the window's start to the training, the training to the
    # conversation, the conversation to the window's end
    "months": ("2026-01-01T00:00:00Z", "2026-04-15T00:00:00Z"),
    # the window's edges a day before the training and a day after the conversation
    "weeks": ("2026-02-01T00:00:00Z", "2026-03-11T00:00:00Z"),
    "no window": ("", ""),
}
# Each tick of the ruler: its text, and whether its box lies inside the ruler's.
TICKS = """() => {
  const ruler = document.querySelector('.tl-ruler').getBoundingClientRect();
  return [...document.querySelectorAll('.tl-tick')].map(tick => {
    const box = tick.getBoundingClientRect();
    return [tick.textContent, box.left >= ruler.left - 0.5 && box.right <= ruler.right + 0.5];
  });
}"""


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
@pytest.mark.parametrize("window", list(WINDOWS))
def test_the_conversation_spreads_over_the_ruler_and_the_lone_event_keeps_its_date(
    demo_stack: UiStack, open_at: Any, viewport: str, window: str
) -> None:
    since, until = WINDOWS[window]
    page = open_at(viewport)
    params = {"robot": ARI, **({"since": since, "until": until} if since else {})}
    visit(page, f"{demo_stack.ui_url}/timeline?{httpx.QueryParams(params)}")
    page.wait_for_selector("#timeline[data-ruler-breaks]")  # the ruler is drawn at the next frame
    page.focus(".tl-list")

    def playhead_at(key: str) -> tuple[str, float]:
        page.keyboard.press(key)
        page.wait_for_timeout(50)
        at = page.evaluate("() => parseFloat(document.querySelector('.tl-playhead').style.left)")
        return page.locator(".tl-current .tl-time").inner_text(), at

    training, lone = playhead_at("Home")
    first, start = playhead_at("ArrowDown")
    last, end = playhead_at("End")
    assert training.startswith("2026-02-02") and first.startswith("2026-03-10") and last.startswith("2026-03-10")
    width = page.evaluate("() => document.querySelector('.tl-ruler').clientWidth")
    assert (end - start) / width >= 0.6, (start, end, width)
    assert 0 <= lone < start  # the training is drawn apart, before the conversation

    ticks = page.evaluate(TICKS)
    assert all(inside for _, inside in ticks), ticks
    assert any(text.startswith("2026-02-02 08:00") for text, _ in ticks), ticks
    assert "36 days" in page.locator(".tl-break-label").all_inner_texts()
    assert axe_violations(page) == []
    assert page.console_errors == []
