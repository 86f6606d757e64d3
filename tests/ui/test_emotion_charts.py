"""The emotion charts in real Chromium say what the readings say: one series per (target, category), a line only
between readings of one category that follow each other, a named scale, and text of one size however many
participants there are. And the timeline's ruler spreads a conversation over its width when one event is weeks
before it."""

from __future__ import annotations

import re
from typing import Any

import httpx
import pytest
from semantic_log_generator import ActivityKind, EmotionScore, SEGBPublisher

from tests.conftest import UiStack
from tests.support.scenarios import at, robot_logger
from tests.support.settle import settle
from tests.ui.conftest import axe_violations, visit

pytestmark = pytest.mark.browser

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
TIAGO = "https://example.org/segb/robots/tiago/v1/robot_tiago"

# Every series of every chart: its target and category, its circles' x, and its path's segments (x1, x2).
DRAWN = """(scope) => [...document.querySelectorAll(scope + " svg.emotion-chart g.series")].map(g => ({
  target: g.dataset.target, category: g.dataset.category,
  dots: [...g.querySelectorAll("circle")].map(c => c.cx.baseVal.value),
  segments: [...g.querySelectorAll("path")].flatMap(p => p.getAttribute("d").split("M").filter(Boolean).flatMap(run => {
    const xs = run.trim().split(/\\s*L\\s*/).map(point => Number(point.split(",")[0]));
    return xs.slice(1).map((x, i) => [xs[i], x]);
  })),
}))"""


def drawn(page: Any, scope: str = "#content") -> list[dict[str, Any]]:
    return list(page.evaluate(DRAWN, scope))


def crossings(series: list[dict[str, Any]]) -> list[str]:
    """Segments that pass over a reading of another category of the same target, or end off their own dots."""
    found = []
    for one in series:
        others = [x for other in series if other["target"] == one["target"] and other is not one for x in other["dots"]]
        for x1, x2 in one["segments"]:
            ends_on_dots = all(any(abs(x - dot) < 0.2 for dot in one["dots"]) for x in (x1, x2))
            if not ends_on_dots or any(x1 < x < x2 for x in others):
                found.append(f"{one['target']} {one['category']} {x1}→{x2}")
    return found


def publish_readings(api_url: str, readings: list[tuple[float, str, float, float]]) -> None:
    """ARI's readings on Maria: (seconds after 09:00, category, intensity, confidence)."""
    ari = robot_logger("ari", "ARI")
    maria = ari.register_human("maria", first_name="Maria")
    for n, (seconds, category, intensity, confidence) in enumerate(readings):
        read = ari.log_activity(
            activity_id=f"read_{n}", activity_kind=ActivityKind.EMOTION_RECOGNITION, started_at=at(seconds)
        )
        ari.log_emotion_annotation(
            source_activity=read, targets=[maria], emotions=[EmotionScore(category, intensity, confidence)]
        )
    ari.publish(SEGBPublisher(base_url=api_url))
    settle(api_url)


def test_a_line_joins_only_readings_of_one_category_that_follow_each_other(ui_stack: UiStack, page: Any) -> None:
    publish_readings(
        ui_stack.api_url,
        [(0, "happiness", 0.5, 0.8), (5, "happiness", 0.6, 0.7), (10, "surprise", 0.8, 0.9),
         (20, "happiness", 0.7, 0.6), (25, "happiness", 0.9, 0.85), (30, "sadness", 0.3, 0.5)],
    )  # fmt: skip
    page.goto(f"{ui_stack.ui_url}/reports/emotion-timeline")
    series = {one["category"]: one for one in drawn(page)}
    assert sorted(series) == ["happiness", "sadness", "surprise"]
    assert len(series["happiness"]["segments"]) == 2  # 0→5 and 20→25, never 5→20 across the surprise
    assert series["surprise"]["segments"] == series["sadness"]["segments"] == []
    assert crossings(list(series.values())) == []
    title = page.locator("g.series[data-category=happiness] circle title").first.text_content()
    assert title == "2026-03-10 09:00:00 · happiness: intensity 0.50, confidence 0.80"


def test_each_series_is_one_target_and_category_and_no_line_crosses_another(demo_stack: UiStack, page: Any) -> None:
    report = httpx.get(f"{demo_stack.ui_url}/reports/emotion-timeline/download.json", timeout=30).json()
    pairs = {(row["target"], row["category"]) for row in report["rows"]}
    read = [row for row in report["rows"] if row["confidence"] is not None]  # the faces read, not the mirrored
    assert len(read) >= 5 and all(row["confidence"] != row["intensity"] for row in read)  # two measures, two values
    for path, scope in (("/reports/emotion-timeline", "#content"), ("/reports", "#report-emotion-timeline")):
        page.goto(demo_stack.ui_url + path)
        series = drawn(page, scope)
        assert len(series) == len(pairs), path
        assert {(one["target"], one["category"]) for one in series} == pairs, path
        assert crossings(series) == [], path


def test_the_scale_is_named_and_explained(demo_stack: UiStack, page: Any) -> None:
    for name in ("emotion-timeline", "extreme-emotions"):
        page.goto(f"{demo_stack.ui_url}/reports/{name}")
        charts = page.locator("svg.emotion-chart")
        assert charts.count() > 0
        assert charts.locator("text.axis-title").all_text_contents() == ["intensity (0\N{EN DASH}1)"] * charts.count()
        assert charts.first.locator("text.y-tick").all_text_contents() == ["0", "0.25", "0.5", "0.75", "1"]
        key = page.locator("#report-" + name + " .chart-key").inner_text()
        assert "Each dot is one reading" in key and "0 none, 1 the strongest" in key
        assert "A line joins readings of one emotion only where no reading of another emotion comes between" in key
        assert axe_violations(page) == []


def test_one_participants_chart_has_text_no_larger_than_many(demo_stack: UiStack, open_at: Any) -> None:
    rows = httpx.get(f"{demo_stack.ui_url}/reports/emotion-timeline/download.json", timeout=30).json()["rows"]
    carlos = next(row["target"] for row in rows if row["targetName"] == "Carlos")
    tick_height = "() => document.querySelector('svg.emotion-chart text.y-tick').getBoundingClientRect().height"
    for viewport in ("desktop", "phone"):
        page = open_at(viewport)
        page.goto(f"{demo_stack.ui_url}/reports/emotion-timeline")
        many = page.locator("svg.emotion-chart").count()
        in_many = page.evaluate(tick_height)
        page.goto(f"{demo_stack.ui_url}/reports/extreme-emotions?{httpx.QueryParams({'human': carlos})}")
        assert page.locator("svg.emotion-chart").count() == 1 < many
        alone = page.evaluate(tick_height)
        assert alone <= in_many + 0.5, (viewport, alone, in_many)
        assert axe_violations(page) == []


def test_the_timeline_ruler_spreads_the_conversation_when_one_event_is_weeks_before(
    demo_stack: UiStack, open_at: Any
) -> None:
    """ARI's model was trained on 2026-02-02; the conversation is on 2026-03-10 and lasts half a minute."""
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/timeline?{httpx.QueryParams({'robot': ARI})}")
    page.wait_for_selector("#timeline[data-ruler-breaks]")  # the ruler is drawn at the next frame
    page.focus(".tl-list")
    place = "() => parseFloat(document.querySelector('.tl-playhead').style.left)"

    def playhead_at(key: str) -> tuple[str, float]:
        page.keyboard.press(key)
        page.wait_for_timeout(50)
        return page.locator(".tl-current .tl-time").inner_text(), page.evaluate(place)

    training, _ = playhead_at("Home")
    first, start = playhead_at("ArrowDown")
    last, end = playhead_at("End")
    assert training.startswith("2026-02-02") and first.startswith("2026-03-10") and last.startswith("2026-03-10")
    width = page.evaluate("() => document.querySelector('.tl-ruler').clientWidth")
    assert (end - start) / width >= 0.8, (start, end, width)
    assert page.locator(".tl-break-label").all_inner_texts() == ["36 days"]
    ticks = page.locator(".tl-tick").all_inner_texts()
    assert any(tick.startswith("2026-02-02") for tick in ticks) and re.search(r"10:00:\d\d$", ticks[-1])
    assert axe_violations(page) == []
    # TIAGo's events, over two minutes with no long quiet stretch: nothing cut out
    visit(page, f"{demo_stack.ui_url}/timeline?{httpx.QueryParams({'robot': TIAGO})}")
    page.wait_for_selector("#timeline[data-ruler-breaks]")  # the ruler is drawn at the next frame
    assert page.locator("#timeline").get_attribute("data-ruler-breaks") == "0"
    assert page.console_errors == []
