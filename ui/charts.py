"""Charts as data for server-rendered SVG: geometry is computed here, `_charts.html` only draws it.

No JavaScript and no inline styles (the CSP forbids them): colours travel as SVG presentation attributes.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from itertools import pairwise
from statistics import median

from segb_server.ui.display import parse_time, short_iri, when
from segb_server.ui.namesakes import Name

# Big Six categories get fixed, distinguishable colours; any other category a robot invents gets a stable
# colour derived from its name.
EMOTION_COLOURS = {
    "happiness": "#e6a700",
    "sadness": "#2f5fd0",
    "anger": "#c62828",
    "fear": "#7b3fb5",
    "disgust": "#2e7d32",
    "surprise": "#00838f",
}
_FALLBACK_COLOURS = ["#8d6e63", "#d81b60", "#546e7a", "#f4511e", "#3949ab", "#00897b"]


def colour_for(category: str) -> str:
    if category in EMOTION_COLOURS:
        return EMOTION_COLOURS[category]
    digest = hashlib.sha256(category.encode()).digest()
    return _FALLBACK_COLOURS[digest[0] % len(_FALLBACK_COLOURS)]


@dataclass(frozen=True)
class Point:
    x: float  # percent of the plot's width
    y: float  # pixels from the chart's top
    title: str


@dataclass(frozen=True)
class Series:
    """One emotion category of one target. `runs` are its readings that follow each other with no reading of
    another category of the same target and no long gap between them: only those are joined by a line."""

    name: str
    colour: str
    points: list[Point]
    runs: list[list[Point]] = field(default_factory=list)

    @property
    def segments(self) -> list[tuple[Point, Point]]:
        """The lines drawn: one between each two readings that follow each other in a run."""
        return [pair for run in self.runs for pair in pairwise(run)]


@dataclass(frozen=True)
class Tick:
    position: float  # pixels from the top on the intensity scale, percent of the plot's width on the time scale
    label: str
    anchor: str = "middle"  # SVG text-anchor: the first and last time labels are kept inside the plot

    @property
    def lines(self) -> list[str]:
        """A time label with its date is drawn on two lines (date, then time), so three fit a phone's width."""
        return self.label.split(" ")


@dataclass
class LineChart:
    """Intensity (0 to 1) over time for one participant, one series per emotion category. Across, places are
    percentages of the plot's width; down, and for text, pixels: the chart stretches to its column while its
    text keeps one size, the same on a phone and on a desktop, beside nineteen other charts or alone. The plot's
    side margins, where the scale's labels go, are the `.chart-plot` padding in segb.css."""

    title: str
    subject: str
    kind: str
    qualifier: str = ""  # what tells this participant from a namesake
    lines: bool = True  # False: dots only (the chart leaves readings out, so a line could pass over one unseen)
    top: int = 30  # room for the scale's name above it
    plot_height: int = 160
    bottom: int = 30  # room for the time labels; a second line when they carry the date
    series: list[Series] = field(default_factory=list)
    x_ticks: list[Tick] = field(default_factory=list)
    y_ticks: list[Tick] = field(default_factory=list)

    @property
    def plot_bottom(self) -> int:
        return self.top + self.plot_height

    @property
    def height(self) -> int:
        return self.plot_bottom + self.bottom


# A line stops where two readings of one target are more than this many times its usual (median) interval apart.
LONG_GAP = 3


def emotion_charts(
    rows: Iterable[Mapping[str, object]], names: Mapping[str, Name], lines: bool = True
) -> list[LineChart]:
    """One chart per emotion target (human or robot), in the order targets first appear; `lines=False` for
    dots only."""
    readings: dict[str, list[Mapping[str, object]]] = {}
    for row in rows:
        if row.get("time") and isinstance(row.get("intensity"), int | float) and row.get("target"):
            readings.setdefault(str(row["target"]), []).append(row)
    return [_emotion_chart(target, target_rows, names.get(target), lines) for target, target_rows in readings.items()]


def _emotion_chart(target: str, rows: list[Mapping[str, object]], name: Name | None, lines: bool) -> LineChart:
    first = rows[0]
    name = name or Name(str(first.get("targetName") or short_iri(target)))
    chart = LineChart(
        title=name.label,
        subject=target,
        kind=str(first.get("targetKind") or "other"),
        qualifier=name.qualifier,
        lines=lines,
    )
    read = sorted(((parse_time(str(row["time"])), row) for row in rows), key=lambda pair: pair[0])
    start, end = read[0][0], read[-1][0]
    span = (end - start).total_seconds()

    def x_of(moment: datetime) -> float:
        return 50.0 if span == 0 else 100 * (moment - start).total_seconds() / span

    def y_of(value: float) -> float:
        return chart.plot_bottom - chart.plot_height * max(0.0, min(1.0, value))

    by_category: dict[str, list[Point]] = {}
    runs: dict[str, list[list[Point]]] = {}
    previous: tuple[datetime, str] | None = None
    long_gap = LONG_GAP * _usual_interval([moment for moment, _ in read])
    for moment, row in read:
        category = str(row.get("category") or "unknown")
        intensity = float(row["intensity"])  # type: ignore[arg-type]
        point = Point(x_of(moment), y_of(intensity), _reading_title(row, category, intensity))
        by_category.setdefault(category, []).append(point)
        # A reading of another category in between, or a long silence: the line stops there.
        joined = previous is not None and previous[1] == category and (moment - previous[0]).total_seconds() <= long_gap
        if not (lines and joined):
            runs.setdefault(category, []).append([])
        runs[category][-1].append(point)
        previous = (moment, category)
    chart.series = [
        Series(category, colour_for(category), points, runs[category])
        for category, points in sorted(by_category.items())
    ]
    chart.y_ticks = [Tick(y_of(value), f"{value:g}") for value in (0.0, 0.25, 0.5, 0.75, 1.0)]
    with_date = start.date() != end.date()
    chart.bottom += 14 if with_date else 0
    middle = start + (end - start) / 2
    places = [(start, "middle")] if span == 0 else [(start, "start"), (middle, "middle"), (end, "end")]
    chart.x_ticks = [
        Tick(x_of(moment), when(moment.isoformat(), with_date=with_date), anchor) for moment, anchor in places
    ]
    return chart


def _usual_interval(moments: list[datetime]) -> float:
    """The median time, in seconds, between a target's readings that follow each other at different times."""
    gaps = [(later - earlier).total_seconds() for earlier, later in pairwise(moments) if later > earlier]
    return median(gaps) if gaps else 0.0


def _reading_title(row: Mapping[str, object], category: str, intensity: float) -> str:
    confidence = row.get("confidence")
    sure = f", confidence {confidence:.2f}" if isinstance(confidence, int | float) else ""
    return f"{when(row['time'])} · {category}: intensity {intensity:.2f}{sure}"


@dataclass(frozen=True)
class Bar:
    label: str
    value: int
    y: float
    width: float
    detail: str


@dataclass
class BarChart:
    """Horizontal bars: activities per model."""

    bars: list[Bar]
    width: int = 640
    label_width: int = 280
    bar_height: int = 22
    gap: int = 8

    @property
    def height(self) -> int:
        return max(1, len(self.bars)) * (self.bar_height + self.gap) + self.gap


def model_usage_chart(rows: Iterable[Mapping[str, object]], names: Mapping[str, Name]) -> BarChart:
    """One bar per model IRI; models that share a label are named with the robots that used them."""
    activities: dict[str, set[str]] = {}
    labels: dict[str, str] = {}
    for row in rows:
        model = str(row.get("model") or "")
        if not model:
            continue
        activities.setdefault(model, set()).add(str(row.get("activity")))
        name = names.get(model) or Name(str(row.get("modelName") or short_iri(model)))
        version = f" {row['version']}" if row.get("version") else ""
        labels[model] = f"{name.label}{version}" + (f" ({name.qualifier})" if name.qualifier else "")
    chart = BarChart(bars=[])
    top = max((len(used) for used in activities.values()), default=1)
    room = chart.width - chart.label_width - 60
    ordered = sorted(activities.items(), key=lambda item: (-len(item[1]), labels[item[0]]))
    chart.bars = [
        Bar(labels[model], len(used), chart.gap + i * (chart.bar_height + chart.gap), room * len(used) / top, model)
        for i, (model, used) in enumerate(ordered)
    ]
    return chart
