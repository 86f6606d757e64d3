"""The emotion charts in real Chromium say what the readings say: one series per (target, category), a line only
between readings of one category that follow each other with no long gap (and none on the extreme-emotions
chart, which leaves readings out), a named scale, and text of the page's size and charts of one size whether there
is one participant or twenty. And the timeline's ruler spreads a conversation over its width when one event is
weeks before it."""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from semantic_log_generator import ActivityKind, EmotionScore, SEGBPublisher

from tests.conftest import UiStack
from tests.support.scenarios import at, robot_logger
from tests.support.settle import settle
from tests.ui.conftest import axe_violations

pytestmark = pytest.mark.browser

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
TIAGO = "https://example.org/segb/robots/tiago/v1/robot_tiago"
EMOTION_PAGES = ("/reports/emotion-timeline", "/reports/extreme-emotions", "/reports")

# Every series of every chart: its target and category, its dots' x and its line segments' (x1, x2), in pixels.
DRAWN = """(scope) => [...document.querySelectorAll(scope + " svg.emotion-chart g.series")].map(g => ({
  target: g.dataset.target, category: g.dataset.category,
  dots: [...g.querySelectorAll("circle")].map(c => c.cx.baseVal.value),
  segments: [...g.querySelectorAll("line")].map(l => [l.x1.baseVal.value, l.x2.baseVal.value]).concat(
    [...g.querySelectorAll("path")].flatMap(p => p.getAttribute("d").split("M").filter(Boolean).flatMap(run => {
      const xs = run.trim().split(/\\s*L\\s*/).map(point => Number(point.split(",")[0]));
      return xs.slice(1).map((x, i) => [xs[i], x]);
    }))),
}))"""

# The size of every chart text as drawn, over the size of the page's own text; each chart's box.
SIZES = """() => {
  const page = parseFloat(getComputedStyle(document.body).fontSize);
  const charts = [...document.querySelectorAll("svg.emotion-chart")];
  return {
    text: charts.flatMap(svg => [...svg.querySelectorAll("text")].map(text =>
      parseFloat(getComputedStyle(text).fontSize) * text.getScreenCTM().a / page)),
    boxes: charts.map(svg => { const box = svg.getBoundingClientRect(); return [box.width, box.height]; }),
    page: document.querySelector("main").getBoundingClientRect().width,
  };
}"""


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


def post_twenty_humans(api_url: str) -> list[str]:
    """ARI's readings on twenty people, posted as one Turtle document; their IRIs."""
    ari = robot_logger("ari", "ARI")
    humans = []
    for n in range(20):
        human = ari.register_human(f"visitor_{n:02d}", first_name=f"Visitor {n + 1}")
        humans.append(str(human))
        for k, (category, intensity, confidence) in enumerate(
            [("happiness", 0.8 + n / 200, 0.7), ("surprise", 0.6, 0.55 + n / 100), ("happiness", 0.9, 0.8)]
        ):
            read = ari.log_activity(
                activity_id=f"read_{n}_{k}", activity_kind=ActivityKind.EMOTION_RECOGNITION, started_at=at(n + 10 * k)
            )
            ari.log_emotion_annotation(
                source_activity=read, targets=[human], emotions=[EmotionScore(category, intensity, confidence)]
            )
    turtle = ari.graph.serialize(format="turtle")
    assert httpx.post(f"{api_url}/ttl", json={"ttl_content": turtle}, timeout=60).status_code == 201
    settle(api_url)
    return humans


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


def test_a_long_gap_between_readings_of_one_category_is_not_bridged(ui_stack: UiStack, page: Any) -> None:
    """Readings every five seconds, then none for a quarter of an hour: dots, no line across the silence."""
    publish_readings(
        ui_stack.api_url,
        [(0, "happiness", 0.5, 0.8), (5, "happiness", 0.6, 0.7), (10, "happiness", 0.7, 0.75),
         (15, "happiness", 0.65, 0.7), (915, "happiness", 0.9, 0.85), (920, "happiness", 0.8, 0.6)],
    )  # fmt: skip
    page.goto(f"{ui_stack.ui_url}/reports/emotion-timeline")
    [happiness] = drawn(page)
    dots = sorted(happiness["dots"])

    def nth(x: float) -> int:
        return min(range(len(dots)), key=lambda n: abs(dots[n] - x))

    assert sorted((nth(x1), nth(x2)) for x1, x2 in happiness["segments"]) == [(0, 1), (1, 2), (2, 3), (4, 5)]
    assert "no longer gap" in page.locator(".chart-key").inner_text()


def test_the_extreme_emotions_chart_draws_dots_only(ui_stack: UiStack, page: Any) -> None:
    """The sadness between the two strong happinesses is below the threshold, so it is not on the chart: a line
    between them would pass over it unseen."""
    publish_readings(
        ui_stack.api_url, [(0, "happiness", 0.9, 0.8), (10, "sadness", 0.3, 0.6), (20, "happiness", 0.85, 0.7)]
    )
    page.goto(f"{ui_stack.ui_url}/reports/extreme-emotions")
    [happiness] = drawn(page)
    assert len(happiness["dots"]) == 2 and happiness["segments"] == []
    key = page.locator(".chart-key").inner_text()
    assert "readings below the threshold are left out" in key and "no line joins" in key
    page.goto(f"{ui_stack.ui_url}/reports/emotion-timeline")
    assert [one["segments"] for one in drawn(page)] == [[], []]
    assert axe_violations(page) == []


def test_each_series_is_one_target_and_category_and_no_line_crosses_another(demo_stack: UiStack, page: Any) -> None:
    report = httpx.get(f"{demo_stack.ui_url}/reports/emotion-timeline/download.json", timeout=30).json()
    read = [row for row in report["rows"] if row["confidence"] is not None]  # the faces read, not the mirrored
    assert len(read) >= 5 and all(row["confidence"] != row["intensity"] for row in read)  # two measures, two values
    extreme = httpx.get(f"{demo_stack.ui_url}/reports/extreme-emotions/download.json", timeout=30).json()["rows"]
    for path, scope, rows in (
        ("/reports/emotion-timeline", "#content", report["rows"]),
        ("/reports", "#report-emotion-timeline", report["rows"]),
        ("/reports/extreme-emotions", "#content", extreme),
        ("/reports", "#report-extreme-emotions", extreme),
    ):
        page.goto(demo_stack.ui_url + path)
        series = drawn(page, scope)
        assert {(one["target"], one["category"]) for one in series} == {
            (row["target"], row["category"]) for row in rows
        }, path
        assert len(series) == len({(row["target"], row["category"]) for row in rows}), path
        assert crossings(series) == [], path
        assert sum(len(one["dots"]) for one in series) == len(rows), path


def test_the_scale_is_named_and_explained(demo_stack: UiStack, page: Any) -> None:
    for name in ("emotion-timeline", "extreme-emotions"):
        page.goto(f"{demo_stack.ui_url}/reports/{name}")
        charts = page.locator("svg.emotion-chart")
        assert charts.count() > 0
        assert charts.locator("text.axis-title").all_text_contents() == ["intensity (0\N{EN DASH}1)"] * charts.count()
        assert charts.first.locator("text.y-tick").all_text_contents() == ["0", "0.25", "0.5", "0.75", "1"]
        key = page.locator("#report-" + name + " .chart-key").inner_text()
        assert "Each dot is one reading" in key and "0 none, 1 the strongest" in key
        assert "confidence" in key
        assert axe_violations(page) == []
    page.goto(f"{demo_stack.ui_url}/reports/emotion-timeline")
    key = page.locator(".chart-key").inner_text()
    assert "A line joins readings of one emotion only where no reading of another emotion comes between" in key


@pytest.mark.parametrize("viewport", ["desktop", "phone"])
def test_chart_text_keeps_the_page_size_with_one_participant_or_twenty(
    ui_stack: UiStack, open_at: Any, viewport: str
) -> None:
    humans = post_twenty_humans(ui_stack.api_url)
    page = open_at(viewport)
    seen = {}
    for path in (
        "/reports/emotion-timeline",
        "/reports",
        "/reports/extreme-emotions?" + str(httpx.QueryParams({"human": humans[7]})),
        "/reports/emotion-timeline?" + str(httpx.QueryParams({"human": humans[0]})),
    ):
        page.goto(ui_stack.ui_url + path)
        sizes = page.evaluate(SIZES)
        assert all(0.7 <= size <= 1.0 for size in sizes["text"]), (path, sorted(set(sizes["text"])))
        seen[path] = sizes
        assert axe_violations(page) == [], path
    many, one = seen["/reports/emotion-timeline"], seen[next(path for path in seen if "extreme" in path)]
    assert len(many["boxes"]) == 20 and len(one["boxes"]) == 1
    boxes = {(round(width), round(height)) for sizes in seen.values() for width, height in sizes["boxes"]}
    assert len(boxes) == 1, boxes  # one participant's chart is as big as each of twenty
    [(width, height)] = boxes
    if viewport == "desktop":
        assert width <= 0.6 * one["page"] and height <= 300, (width, height, one["page"])
    assert page.console_errors == []
