"""The targets the figures are judged against, each with what was measured and a verdict."""

from __future__ import annotations

from typing import TYPE_CHECKING

from bench.crosscheck import UNCHECKED, check_of
from bench.live import LiveReports
from bench.measure import Latency
from bench.names import BASELINE, VIRTUOSO_JOURNAL, VIRTUOSO_STORE

if TYPE_CHECKING:  # report.py imports this module
    from bench.report import Figures

Row = list[str]
POSTS_PER_SECOND = {"embedded": 1000, "virtuoso": 500}


def verdict(ok: bool) -> str:
    return "met" if ok else "**not met**"


def targets(f: Figures) -> list[Row]:
    return [
        *_small(f),
        *_robots(f),
        *_steady(f),
        *_cumulative(f),
        *(row for (store, size), live in f.live.items() for row in _live(store, size, live)),
        *_health(f),
    ]


def _small(f: Figures) -> list[Row]:
    rows = []
    if small := f.small.get("embedded"):
        p50, p99 = small.latency.p50, small.latency.p99
        rows.append(["small posts, embedded: p50 ≤ 2 ms, p99 ≤ 10 ms", f"p50 {p50:.2f} ms, p99 {p99:.2f} ms",
                     verdict(p50 <= 2 and p99 <= 10)])  # fmt: skip
    naive = f.small.get(BASELINE)
    for name in (VIRTUOSO_JOURNAL, VIRTUOSO_STORE):
        if naive and (ours := f.small.get(name)):
            ratio = naive.latency.p50 / ours.latency.p50
            rows.append([f"small posts, {name}: p50 ≥ 5x faster than the naive baseline",
                         f"{ratio:.2f}x ({ours.latency.p50:.2f} ms against {naive.latency.p50:.2f} ms)",
                         verdict(ratio >= 5)])  # fmt: skip
    return rows


def _robots(f: Figures) -> list[Row]:
    rows = []
    for store, rate in POSTS_PER_SECOND.items():
        if (robots := f.robots.get(store)) is None:
            continue
        lost = robots.triples_sent - robots.triples_stored
        rows.append([
            f"16 robots, {store}: ≥ {rate:,} posts/s, p99 ≤ 50 ms, 0 errors, every triple stored",
            f"{robots.posts_per_second:.0f} posts/s, p99 {robots.latency.p99:.1f} ms, {robots.errors} errors, "
            f"{lost} triples missing",
            verdict(robots.posts_per_second >= rate and robots.latency.p99 <= 50 and not robots.errors and not lost),
        ])  # fmt: skip
    return rows


def _steady(f: Figures) -> list[Row]:
    rows = []
    for store, run in f.steady.items():
        if run.visible is None:
            rows.append([f"apply lag at 10 posts/s, {store}: p99 ≤ 1 s", "nothing became visible", verdict(False)])
            continue
        rows.append([
            f"apply lag at 10 posts/s, {store}: p99 ≤ 1 s (201 to visible through /sparql)",
            f"p50 {run.visible.p50:.0f} ms, p99 {run.visible.p99:.0f} ms, {run.not_visible} never visible",
            verdict(run.visible.p99 <= 1000 and not run.not_visible),
        ])  # fmt: skip
    return rows


def _cumulative(f: Figures) -> list[Row]:
    return [
        [f"cumulative re-publish, {name}: ≤ 1 s per post (at {run.last.interactions} interactions)",
         f"{run.last.seconds:.2f} s for {run.last.payload_triples:,} triples", verdict(run.last.seconds <= 1)]
        for name, run in f.cumulative.items()
    ]  # fmt: skip


def _live(store: str, size: int, live: LiveReports) -> list[Row]:
    pages = [(f"{p.report} {p.variant}", p.first) for p in live.pages]
    pages += [(f"{p.report} {p.variant}, next", p.next) for p in live.pages if p.next]
    rows = []
    if pages:
        worst50 = max(pages, key=lambda item: item[1].p50)
        worst95 = max(pages, key=lambda item: item[1].p95)
        rows.append([
            f"reports at {size:,} triples, {store}, under live ingest: first and next pages p50 ≤ 50 ms, p95 ≤ 150 ms",
            f"worst p50 {worst50[1].p50:.1f} ms ({worst50[0]}), worst p95 {worst95[1].p95:.1f} ms ({worst95[0]}); "
            f"{len(pages)} pages",
            verdict(worst50[1].p50 <= 50 and worst95[1].p95 <= 150 and not any(p.failure for p in live.pages)),
        ])  # fmt: skip
    if live.views:
        worst50v = max(live.views.items(), key=lambda item: item[1].latency.p50)
        worst95v = max(live.views.items(), key=lambda item: item[1].latency.p95)
        rows.append([
            f"graph views and explanation at {size:,} triples, {store}, under live ingest: p50 ≤ 50 ms, p95 ≤ 150 ms",
            f"worst p50 {worst50v[1].latency.p50:.1f} ms ({worst50v[0]}), worst p95 {worst95v[1].latency.p95:.1f} ms "
            f"({worst95v[0]})",
            verdict(worst50v[1].latency.p50 <= 50 and worst95v[1].latency.p95 <= 150
                    and not any(view.failure for view in live.views.values())),
        ])  # fmt: skip
    checks = [(f"{p.report} {p.variant}", check_of(p)) for p in live.pages]
    wrong = [name for name, rows in checks if rows and rows != UNCHECKED]
    unchecked = [name for name, rows in checks if rows == UNCHECKED]
    rows.append([
        f"reports at {size:,} triples, {store}: empty filtered pages agree with the report's query",
        f"{len(wrong)} disagree" + (f" ({', '.join(wrong)})" if wrong else "")
        + (f"; {len(unchecked)} could not be checked ({', '.join(unchecked)})" if unchecked else ""),
        verdict(not wrong) if not unchecked else "unknown" if not wrong else verdict(False),
    ])  # fmt: skip
    visible = Latency.of(live.background.visible) if live.background.visible else None
    rows.append([
        f"a post's rows in its report ≤ 1 s after its 201, {store}, {size:,} triples (p99)",
        f"p50 {visible.p50:.0f} ms, p99 {visible.p99:.0f} ms, max {visible.max:.0f} ms, "
        f"{live.background.not_visible} never" if visible else "nothing measured",
        verdict(visible is not None and visible.p99 <= 1000 and not live.background.not_visible),
    ])  # fmt: skip
    if live.in_page is not None:
        shown = live.in_page.shown
        rows.append([
            f"a post's message in an open conversations page (Chromium) ≤ 1 s after its 201, {store}, {size:,} "
            "triples (p99)",
            f"p50 {shown.p50:.0f} ms, p99 {shown.p99:.0f} ms, max {shown.max:.0f} ms, "
            f"{live.in_page.never_shown} never of {live.in_page.posts}" if shown
            else live.in_page.failure or "nothing measured",
            verdict(shown is not None and shown.p99 <= 1000 and not live.in_page.never_shown),
        ])  # fmt: skip
    return rows


def _health(f: Figures) -> list[Row]:
    if not f.health_under_load:
        return []
    p99 = f.health_under_load.p99
    return [["health p99 ≤ 100 ms during heavy ingest", f"p99 {p99:.1f} ms", verdict(p99 <= 100)]]
