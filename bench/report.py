"""Turning measured figures into the console table and docs/performance.md."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from bench.analysis import breakdown_section, memory_section, robots_section, virtuoso_floor_section
from bench.measure import Latency
from bench.runs import Cumulative, ManyRobots, ReportFigures, SmallPosts
from bench.virtuoso import Floor

# Why the first query after a write grows with the graph, and what a bounded cost would take.
REPORTS_EXPLAINED = [
    "**Why a report's first query after a write grows with the graph.** Every report is an aggregate or a",
    "sorted join over the whole graph: participants counts the activities of each human-robot pair, and the",
    "timelines and conversations sort every emotion and message before the first page is cut. So the query",
    "costs time in proportion to the activities logged, on both stores; the cache only helps until the next",
    "write. On Virtuoso, participants (a four-branch UNION with a FILTER EXISTS) and the emotion timelines",
    "are far slower than on the embedded store (their plans are not profiled yet). A bounded cost at 1M would take",
    "maintaining each report's rows incrementally at ingest (a post's new triples touch only the rows of its",
    "own activities, messages and emotions), kept in sort order so a page is a range scan; or a default time",
    "window so a query touches a bounded slice. Neither is built. Virtuoso gets no result cache because",
    "another writer could change it unseen; where this server is its only writer (the compose stack), the",
    "embedded store's version-keyed cache would apply there too.",
    "",
]


@dataclass
class Figures:
    profile: str
    machine: dict[str, str]
    small: dict[str, SmallPosts] = field(default_factory=dict)
    robots: dict[str, ManyRobots] = field(default_factory=dict)
    cumulative: dict[str, Cumulative] = field(default_factory=dict)
    health_under_load: Latency | None = None
    reports: dict[tuple[str, int], dict[str, ReportFigures | str]] = field(default_factory=dict)
    peak_rss_mib: dict[tuple[str, int], float | None] = field(default_factory=dict)
    client_floor: SmallPosts | None = None
    robots_floor: ManyRobots | None = None
    breakdown: dict[str, Latency] = field(default_factory=dict)
    virtuoso_floor: Floor | None = None
    wall_seconds: float = 0.0

    def console_table(self) -> str:
        return "\n".join(line for line in _sections(self) if not line.startswith("<!--"))


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return [
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---" if i == 0 else "--:" for i in range(len(header))) + "|",
        *("| " + " | ".join(row) + " |" for row in rows),
        "",
    ]


def _floor_row(f: Figures) -> list[tuple[str, SmallPosts]]:
    return [("no-op server (client + HTTP only)", f.client_floor)] if f.client_floor else []


def _robots_floor_row(f: Figures) -> list[tuple[str, ManyRobots]]:
    return [("no-op server (client + HTTP only)", f.robots_floor)] if f.robots_floor else []


def _verdict(ok: bool) -> str:
    return "met" if ok else "**not met**"


def _sections(f: Figures) -> list[str]:
    lines: list[str] = []
    if f.small:
        lines += ["### 1. Small posts (one event's delta, sequential, one client)", ""]
        lines += _table(
            ["server", "triples/post", "n", "p50 ms", "p95 ms", "p99 ms", "max ms", "posts/s"],
            [
                [
                    name,
                    f"{s.triples_per_post:.0f}",
                    *s.latency.cells()[:1],
                    *s.latency.cells()[1:],
                    f"{s.posts_per_second:.0f}",
                ]
                for name, s in [*f.small.items(), *_floor_row(f)]
            ],
        )
        if f.client_floor:
            lines += [
                "The no-op server answers at once (bench/null_server.py, same uvicorn HTTP parser and loop): its",
                f"{f.client_floor.latency.p50:.2f} ms p50 is the client's own time plus loopback and HTTP, included"
                " in every row",
                "above. The bench client is the standard library's `http.client`; httpx costs about 0.5 ms more",
                "per request.",
                "",
            ]
        lines += breakdown_section(f.breakdown, f.small.get("embedded"), f.client_floor)
        if "virtuoso" in f.small and "naive baseline" in f.small:
            ours, naive = f.small["virtuoso"], f.small["naive baseline"]
            speedup = naive.latency.p50 / ours.latency.p50
            throughput = ours.posts_per_second / naive.posts_per_second
            lines += [
                f"On Virtuoso, against the naive baseline in the same run: p50 {speedup:.2f}x faster, "
                f"throughput {throughput:.2f}x.",
                "",
            ]
    if f.robots:
        lines += ["### 2. Many robots (concurrent clients, each posting its own events)", ""]
        lines += _table(
            [
                "server",
                "posts",
                "p50 ms",
                "p95 ms",
                "p99 ms",
                "max ms",
                "posts/s",
                "triples/s",
                "errors",
                "triples sent",
                "stored",
            ],
            [
                [
                    name,
                    *r.latency.cells(),
                    f"{r.posts_per_second:.0f}",
                    f"{r.triples_per_second:.0f}",
                    str(r.errors),
                    str(r.triples_sent),
                    str(r.triples_stored) if r is not f.robots_floor else "n/a",
                ]
                for name, r in [*f.robots.items(), *_robots_floor_row(f)]
            ],
        )
        lines += robots_section(f.robots.get("embedded"), f.robots_floor)
    if f.cumulative:
        lines += ["### 3. Cumulative re-publish (the whole graph after every interaction)", ""]
        for name, run in f.cumulative.items():
            step = max(1, len(run.points) // 10)
            picked = run.points[step - 1 :: step]
            if picked[-1] is not run.last:
                picked.append(run.last)
            lines += [f"**{name}**", ""]
            lines += _table(
                ["interactions", "payload triples", "payload MB", "new triples", "latency ms"],
                [
                    [
                        str(p.interactions),
                        str(p.payload_triples),
                        f"{p.payload_bytes / 1e6:.2f}",
                        str(p.new_triples),
                        f"{p.seconds * 1000:.0f}",
                    ]
                    for p in picked
                ],
            )
    if any(f.reports.values()):
        lines += [
            "### 4. Report queries (`GET /reports/{name}`, default parameters, first page of up to 1,000 rows)",
            "",
            "Repeated requests are answered from the result cache on the embedded store (the cache is dropped",
            "by every write); the last two columns are the first request after a write, i.e. the query itself.",
            "Virtuoso has no cache (another writer could change it unseen), so both are the query.",
            "",
        ]
        rows = []
        for (store, size), reports in f.reports.items():
            for name, measured in reports.items():
                if isinstance(measured, str):
                    rows.append([store, f"{size:,}", name, f"failed: {measured}", "", "", "", ""])
                    continue
                latency, count, fresh = measured
                rows.append(
                    [store, f"{size:,}", name, str(count), f"{latency.p50:.1f}", f"{latency.p95:.1f}",
                     f"{fresh.p50:.1f}", f"{fresh.p95:.1f}"]
                )  # fmt: skip
        headers = ["store", "triples", "report", "rows", "p50 ms", "p95 ms", "after write p50", "after write p95"]
        lines += _table(headers, rows)
        lines += REPORTS_EXPLAINED
    if f.health_under_load:
        h = f.health_under_load
        lines += ["### 5. Health under load (`/healthz/ready` while workload 3 runs on the embedded store)", ""]
        lines += _table(["n", "p50 ms", "p95 ms", "p99 ms", "max ms"], [h.cells()])
    lines += memory_section(f.peak_rss_mib)
    if f.virtuoso_floor and "virtuoso" in f.small and "naive baseline" in f.small:
        lines += virtuoso_floor_section(f.virtuoso_floor, f.small["virtuoso"], f.small["naive baseline"])
    lines += ["### Targets", "", *_table(["target", "measured", "verdict"], _targets(f))]
    return lines


def _targets(f: Figures) -> list[list[str]]:
    rows = []
    if small := f.small.get("embedded"):
        rows.append(
            [
                "small posts, embedded: p50 ≤ 2 ms, p99 ≤ 10 ms",
                f"p50 {small.latency.p50:.2f} ms, p99 {small.latency.p99:.2f} ms",
                _verdict(small.latency.p50 <= 2 and small.latency.p99 <= 10),
            ]
        )
    if "virtuoso" in f.small and "naive baseline" in f.small:
        ratio = f.small["naive baseline"].latency.p50 / f.small["virtuoso"].latency.p50
        rows.append(["small posts, Virtuoso: ≥ 5x the naive baseline", f"{ratio:.2f}x (p50)", _verdict(ratio >= 5)])
    if robots := f.robots.get("embedded"):
        rows.append(
            [
                "16 robots, embedded: ≥ 1,000 posts/s, p99 ≤ 50 ms, 0 errors, 0 lost",
                f"{robots.posts_per_second:.0f} posts/s, p99 {robots.latency.p99:.1f} ms, {robots.errors} errors, "
                f"{robots.triples_sent - robots.triples_stored} lost",
                _verdict(
                    robots.posts_per_second >= 1000
                    and robots.latency.p99 <= 50
                    and robots.errors == 0
                    and robots.triples_stored == robots.triples_sent
                ),
            ]
        )
    for name, run in f.cumulative.items():
        rows.append(
            [
                f"cumulative re-publish, {name}: ≤ 1 s per post (at {run.last.interactions} interactions)",
                f"{run.last.seconds:.2f} s for {run.last.payload_triples:,} triples",
                _verdict(run.last.seconds <= 1),
            ]
        )
    if f.reports:
        largest = max(size for _, size in f.reports)
        for (store, size), reports in f.reports.items():
            measured = [figures for figures in reports.values() if not isinstance(figures, str)]
            failed = len(reports) - len(measured)
            if size == largest and measured:
                for kind, pick in (("repeated", 0), ("first after a write", 2)):
                    worst50 = max(figures[pick].p50 for figures in measured)  # type: ignore[union-attr]
                    worst95 = max(figures[pick].p95 for figures in measured)  # type: ignore[union-attr]
                    rows.append(
                        [
                            f"every report at {size:,} triples, {store}, {kind}: p50 ≤ 50 ms, p95 ≤ 150 ms",
                            f"worst p50 {worst50:.1f} ms, worst p95 {worst95:.1f} ms"
                            + (f", {failed} failed" if failed else ""),
                            _verdict(worst50 <= 50 and worst95 <= 150 and not failed),
                        ]
                    )
    if f.health_under_load:
        rows.append(
            [
                "health p99 ≤ 100 ms during heavy ingest",
                f"p99 {f.health_under_load.p99:.1f} ms",
                _verdict(f.health_under_load.p99 <= 100),
            ]
        )
    return rows


def write_report(f: Figures, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    header = [
        "# Performance",
        "",
        f"Measured {datetime.now(UTC):%Y-%m-%d} with `python -m bench --profile {f.profile}` "
        f"({f.wall_seconds:.0f} s). Server and clients on one machine, over loopback HTTP; each server runs in",
        "its own process. Payloads come from the emotion-mirror robot (`examples/emotion_mirror`) logging with",
        "the PyPI client `semantic-log-generator` 1.0.5. The naive baseline (`bench/baseline.py`) is the",
        "reference backend's ingest: rdflib parse and one `INSERT DATA` per post, blocking inside an async handler.",
        "",
        "Machine: " + "; ".join(f"{key} {value}" for key, value in f.machine.items()) + ".",
        "",
        "Reproduce: `python -m bench` (quick, about 2 minutes on 2 cores) or `python -m bench --profile full`",
        "(the issue's sizes: 1,000 interactions, reports at 1M triples; expect well over half an hour).",
        "",
    ]
    path.write_text("\n".join(header + _sections(f)) + "\n", encoding="utf-8")
