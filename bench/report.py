"""Turning measured figures into the console table and docs/performance.md."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from bench import analysis
from bench.crosscheck import UNCHECKED, check_of
from bench.freshness import SteadyLag
from bench.live import LiveReports
from bench.measure import Latency
from bench.names import BASELINE, NO_OP, VIRTUOSO_JOURNAL, VIRTUOSO_STORE
from bench.republish import Republish, republish_section
from bench.runs import Cumulative, ManyRobots, SmallPosts
from bench.tables import table
from bench.targets import targets
from bench.virtuoso import Floor


@dataclass
class Figures:
    profile: str
    machine: dict[str, str]
    virtuoso: bool = True
    small: dict[str, SmallPosts] = field(default_factory=dict)
    robots: dict[str, ManyRobots] = field(default_factory=dict)
    steady: dict[str, SteadyLag] = field(default_factory=dict)
    cumulative: dict[str, Cumulative] = field(default_factory=dict)
    republish: dict[str, list[Republish]] = field(default_factory=dict)  # by store
    health_under_load: Latency | None = None
    live: dict[tuple[str, int], LiveReports] = field(default_factory=dict)
    peak_rss_mib: dict[tuple[str, int], float | None] = field(default_factory=dict)
    client_floor: SmallPosts | None = None
    robots_floor: ManyRobots | None = None
    breakdown: dict[str, Latency] = field(default_factory=dict)
    virtuoso_floor: Floor | None = None
    wall_seconds: float = 0.0
    finished: datetime | None = None
    failures: list[str] = field(default_factory=list)  # runs that stopped before the end
    added_runs: list[str] = field(default_factory=list)  # where figures added from other runs come from
    code: str = ""  # what was measured: a commit
    command: str = ""  # how it was measured (the bench's arguments)
    load_at_end: str = ""

    def add_reports(self, other: Figures) -> None:
        """Section 5's sizes measured by another run (a longer profile) that this one lacks."""
        self.__dict__.setdefault("added_runs", [])  # figures saved before this field existed
        added = [key for key in other.live if key not in self.live]
        for key in added:
            self.live[key] = other.live[key]
            for process in (f"API process, {key[0]}", "virtuoso-t (whole run so far)"):
                if (process, key[1]) in other.peak_rss_mib:
                    self.peak_rss_mib[(process, key[1])] = other.peak_rss_mib[(process, key[1])]
        longer = {
            f"{name}, {run.last.interactions:,} interactions ({other.profile} profile)": run
            for name, run in other.cumulative.items()
            if name in self.cumulative and run.last.interactions > self.cumulative[name].last.interactions
        }
        self.cumulative.update(longer)
        if longer:
            self.added_runs.append(f"Section 4 also holds {', '.join(longer)} from the run below.")
        if added:
            sizes = ", ".join(f"{store} {size:,}" for store, size in added)
            finished = f"{other.finished:%Y-%m-%d}" if other.finished else "another day"
            self.added_runs.append(
                f"Section 5's rows for {sizes} triples come from `{_command(other)}`"
                + (f" ({other.code})" if other.code and other.code != self.code else "")
                + f", run on the same machine on {finished} "
                f"({other.wall_seconds:.0f} s, load average at start {other.machine.get('load average at start')})."
            )

    def console_table(self) -> str:
        return "\n".join(_sections(self))


def _command(f: Figures) -> str:
    """How the run was started: its recorded command, or (figures saved before it was kept) its profile."""
    return getattr(f, "command", "") or f"python -m bench --profile {f.profile}{'' if f.virtuoso else ' --no-virtuoso'}"


def _sections(f: Figures) -> list[str]:
    return [
        *_small_section(f),
        *_robots_section(f),
        *_steady_section(f),
        *_cumulative_section(f),
        *republish_section(getattr(f, "republish", {})),  # figures saved before it have none
        *_live_section(f),
        *_health_section(f),
        *analysis.memory_section(f.peak_rss_mib),
        *_floor_section(f),
        *_failures_section(f),
        "### Targets",
        "",
        *table(["target", "measured", "verdict"], targets(f)),
    ]


def _failures_section(f: Figures) -> list[str]:
    if not f.failures:
        return []
    return ["### Runs that stopped", "", *(f"* {failure}" for failure in f.failures), ""]


def _small_section(f: Figures) -> list[str]:
    if not f.small:
        return []
    rows = [*f.small.items(), *([(NO_OP, f.client_floor)] if f.client_floor else [])]
    lines = ["### 1. Small posts (one event's delta, sequential, one client)", ""]
    lines += table(
        ["server", "triples/post", "n", "p50 ms", "p95 ms", "p99 ms", "max ms", "posts/s"],
        [[name, f"{s.triples_per_post:.0f}", *s.latency.cells(), f"{s.posts_per_second:.0f}"] for name, s in rows],
    )
    if f.client_floor:
        lines += analysis.client_floor_note(f.client_floor)
    lines += analysis.breakdown_section(f.breakdown, f.small.get("embedded"), f.client_floor)
    lines += _baseline_ratio(f)
    return lines


def _baseline_ratio(f: Figures) -> list[str]:
    naive = f.small.get(BASELINE)
    if naive is None:
        return []
    lines = ["Against the naive baseline in the same run (its p50 over ours):", ""]
    for name in (VIRTUOSO_JOURNAL, VIRTUOSO_STORE):
        if ours := f.small.get(name):
            lines.append(
                f"* {name}: p50 {naive.latency.p50 / ours.latency.p50:.2f}x faster, p99 "
                f"{naive.latency.p99 / ours.latency.p99:.2f}x, throughput "
                f"{ours.posts_per_second / naive.posts_per_second:.2f}x."
            )
    lines += ["", *analysis.REFERENCE_NOTE]
    return lines


def _robots_section(f: Figures) -> list[str]:
    if not f.robots:
        return []
    rows = [*f.robots.items(), *([(NO_OP, f.robots_floor)] if f.robots_floor else [])]
    lines = ["### 2. Many robots (concurrent clients, each posting its own events)", ""]
    lines += table(
        ["server", "posts", "p50 ms", "p95 ms", "p99 ms", "max ms", "posts/s", "triples/s", "errors",
         "triples sent", "stored"],
        [[name, *r.latency.cells(), f"{r.posts_per_second:.0f}", f"{r.triples_per_second:.0f}", str(r.errors),
          str(r.triples_sent), str(r.triples_stored) if r is not f.robots_floor else "n/a"] for name, r in rows],
    )  # fmt: skip
    lagged = [(name, r.lag) for name, r in f.robots.items() if r.lag is not None]
    if lagged:
        lines += [
            "Readiness during the run (`/healthz/ready` every 50 ms) and after it (polled every 20 ms until",
            "neither `apply_lag` nor `reports_lag` is reported):",
            "",
        ]
        lines += table(
            ["server", "samples", "samples behind", "max apply_lag entries", "max apply_lag s",
             "max reports_lag entries", "store caught up after s", "reports caught up after s"],
            [[name, str(lag.samples), str(lag.behind_samples), str(lag.max_entries), f"{lag.max_seconds:.3f}",
              str(lag.max_reports_entries), _seconds(lag.drain.apply_seconds), _seconds(lag.drain.reports_seconds)]
             for name, lag in lagged],
        )  # fmt: skip
    lines += analysis.robots_notes(f.robots.get("embedded"), f.robots_floor)
    lines += analysis.workers_notes(f.robots)
    return lines


def _steady_section(f: Figures) -> list[str]:
    if not f.steady:
        return []
    lines = [
        "### 3. Apply lag at a steady rate (one robot, 10 posts/s, `INGEST_ACK=journal` on both stores)",
        "",
        "From each post's 201 until a triple unique to that post is read from the store (`/resource`, run",
        "in-process: the applier has written it), and until an `ASK` for it through `/sparql` answers true. Each",
        "reader polls every 5 ms in a thread of its own; a reader still busy when the next post is answered",
        "skips to the newest post instead of timing one late, so *n* is how many posts it timed.",
        "",
    ]
    rows = []
    for name, run in f.steady.items():
        posted = f"{run.post_latency.p50:.1f} / {run.post_latency.p99:.1f}"
        rows.append([name, str(run.posts), f"{run.rate:.1f}", posted, *_lag_cells(run.applied),
                     *_lag_cells(run.visible), str(run.not_visible), str(run.errors)])  # fmt: skip
    lines += table(
        ["store", "posts", "posts/s", "post p50 / p99 ms", "in store n", "p50 / p99 / max ms", "/sparql n",
         "p50 / p99 / max ms", "never visible", "errors"],
        rows,
    )  # fmt: skip
    return lines + analysis.steady_notes(f.steady)


def _cumulative_section(f: Figures) -> list[str]:
    if not f.cumulative:
        return []
    lines = ["### 4. Cumulative re-publish (the whole graph after every interaction, the PyPI client's way)", ""]
    for name, run in f.cumulative.items():
        lines += [f"**{name}**", "", *table(
            ["interactions", "payload triples", "payload MB", "new triples", "latency ms"],
            [[str(p.interactions), str(p.payload_triples), f"{p.payload_bytes / 1e6:.2f}", str(p.new_triples),
              f"{p.seconds * 1000:.0f}"] for p in _tenths(run)],
        )]  # fmt: skip
    journaled = [(name, run.journal) for name, run in f.cumulative.items() if run.journal]
    if journaled:
        lines += [
            "The journal on disk after the last post (`DATA_DIR/journal.sqlite3` and its `-wal`), against the final",
            "graph as N-Triples (the server's own export) and everything the robot sent:",
            "",
        ]
        lines += table(
            ["store", "interactions", "journal MB", "of which -wal MB", "graph triples", "graph N-Triples MB",
             "journal / N-Triples", "without -wal / N-Triples", "sent MB", "reports' rows MB"],
            [[name, str(f.cumulative[name].last.interactions), _mb(j.database_bytes + j.wal_bytes),
              _mb(j.wal_bytes), str(j.graph_triples), _mb(j.graph_ntriples_bytes),
              f"{(j.database_bytes + j.wal_bytes) / j.graph_ntriples_bytes:.2f}",
              f"{j.database_bytes / j.graph_ntriples_bytes:.2f}", _mb(j.payload_bytes),
              _mb(getattr(j, "reports_bytes", 0))]
             for name, j in journaled],
        )  # fmt: skip
        lines += analysis.JOURNAL_SIZE_NOTE
    return lines


def _lag_cells(latency: Latency | None) -> list[str]:
    if latency is None:
        return ["0", "-"]
    return [str(latency.n), f"{latency.p50:.0f} / {latency.p99:.0f} / {latency.max:.0f}"]


def _tenths(run: Cumulative) -> list:  # type: ignore[type-arg]
    step = max(1, len(run.points) // 10)
    picked = run.points[step - 1 :: step]
    if picked[-1] is not run.last:
        picked.append(run.last)
    return picked


def _live_section(f: Figures) -> list[str]:
    if not f.live:
        return []
    lines = [
        "### 5. Reports under live ingest",
        "",
        *analysis.LIVE_INTRO,
        "",
        "**Loading and start-up**",
        "",
        *table(
            ["store", "triples", "load (`segb import`) s", "server ready s", "every view built s",
             "slowest build (report, keys, s)"],
            [[store, f"{size:,}", f"{live.load_seconds:.1f}", f"{live.ready_seconds:.1f}",
              _seconds(live.rows_seconds), _slowest_build(live)] for (store, size), live in f.live.items()],
        ),
        "**Pages** (p50 / p95 ms; *next* is the page after it through the `next` cursor)",
        "",
    ]  # fmt: skip
    rows = []
    for (store, size), live in f.live.items():
        for page in live.pages:
            following = f"{page.next.p50:.1f} / {page.next.p95:.1f}" if page.next else "no next page"
            if page.failure:
                following += f"; failed: {page.failure}"
            count = str(page.rows)
            checked = check_of(page)
            if checked == UNCHECKED:
                count += " (its query could not be run to check)"
            elif checked:
                count += f" (**its query: {checked}**)"
            rows.append([store, f"{size:,}", page.report, page.variant, count, page.served_from,
                         f"{page.first.p50:.1f} / {page.first.p95:.1f}", following])  # fmt: skip
    lines += table(["store", "triples", "report", "filters", "rows", "served from", "first page", "next page"], rows)
    lines += ["**Graph and explanation** (p50 / p95 ms)", ""]
    lines += table(
        ["store", "triples", "view", "n", "p50 / p95 ms", "failed"],
        [[store, f"{size:,}", view, str(got.latency.n), f"{got.latency.p50:.1f} / {got.latency.p95:.1f}",
          got.failure or "-"] for (store, size), live in f.live.items() for view, got in live.views.items()],
    )  # fmt: skip
    lines += ["**The robot publishing meanwhile, and its rows**", ""]
    lines += table(
        [
            "store",
            "triples",
            "posts",
            "posts/s",
            "post p50 / p99 ms",
            "errors",
            "rows visible after 201 p50 / p99 ms",
            "n",
            "never visible",
            "max reports_lag entries",
        ],
        [_background_row(store, size, live) for (store, size), live in f.live.items()],
    )
    lines += ["**The robot's conversations open in Chromium** (201 to its messages shown in the page)", ""]
    lines += table(
        ["store", "triples", "posts watched", "p50 / p95 / p99 / max ms", "never shown", "not watched because"],
        [_in_page_row(store, size, live) for (store, size), live in f.live.items()],
    )
    return lines + analysis.live_notes(f.live)


def _in_page_row(store: str, size: int, live: LiveReports) -> list[str]:
    watched = live.in_page
    if watched is None:
        return [store, f"{size:,}", "-", "-", "-", "not measured in this run"]
    shown = watched.shown
    figures = f"{shown.p50:.0f} / {shown.p95:.0f} / {shown.p99:.0f} / {shown.max:.0f}" if shown else "-"
    return [store, f"{size:,}", str(watched.posts), figures, str(watched.never_shown), watched.failure or "-"]


def _background_row(store: str, size: int, live: LiveReports) -> list[str]:
    robot = live.background
    posted = Latency.of(robot.latencies) if robot.latencies else None
    visible = Latency.of(robot.visible) if robot.visible else None
    return [
        store,
        f"{size:,}",
        str(robot.posts),
        f"{robot.rate:.1f}",
        f"{posted.p50:.1f} / {posted.p99:.1f}" if posted else "-",
        str(robot.errors),
        f"{visible.p50:.0f} / {visible.p99:.0f}" if visible else "-",
        str(visible.n if visible else 0),
        str(robot.not_visible),
        str(live.lag.max_reports_entries),
    ]


def _slowest_build(live: LiveReports) -> str:
    if not live.built:
        return "-"
    name, (keys, seconds) = max(live.built.items(), key=lambda item: item[1][1])
    return f"{name}, {keys:,}, {seconds:.1f}"


def _health_section(f: Figures) -> list[str]:
    if not f.health_under_load:
        return []
    return [
        "### 6. Health under load (`/healthz/ready` every 20 ms while workload 4 runs on the embedded store)",
        "",
        *table(["n", "p50 ms", "p95 ms", "p99 ms", "max ms"], [f.health_under_load.cells()]),
    ]


def _floor_section(f: Figures) -> list[str]:
    ours, naive = f.small.get(VIRTUOSO_STORE), f.small.get(BASELINE)
    if f.virtuoso_floor is None or ours is None or naive is None:
        return []
    lines = analysis.virtuoso_floor_section(f.virtuoso_floor, ours, f.small.get(VIRTUOSO_JOURNAL), naive)
    return lines + analysis.journal_ack_note(f.breakdown, f.client_floor, f.small.get(VIRTUOSO_JOURNAL), naive)


def _seconds(value: float | None) -> str:
    return "not within the wait" if value is None else f"{value:.2f}"


def _mb(size: int) -> str:
    return f"{size / 1e6:.2f}"


def write_report(f: Figures, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    header = [
        "# Performance",
        "",
        f"Measured {f.finished or datetime.now(UTC):%Y-%m-%d} with `{_command(f)}` ({f.wall_seconds:.0f} s). Server"
        " and clients on one machine,"
        " over loopback HTTP; each server runs in",
        "its own process. Payloads come from the emotion-mirror robot (`examples/emotion_mirror`) logging with",
        "the PyPI client `semantic-log-generator` 1.0.5. The naive baseline (`bench/baseline.py`) is the",
        "reference backend's ingest: rdflib parse and one `INSERT DATA` per post, blocking inside an async handler.",
        "",
        *([f"Code measured: {f.code}.", ""] if getattr(f, "code", "") else []),
        "Machine: "
        + "; ".join(f"{key} {value}" for key, value in f.machine.items())
        + (f"; load average at the end {f.load_at_end}" if getattr(f, "load_at_end", "") else "")
        + ".",
        "",
        *analysis.MACHINE_NOTE,
        "",
        "Reproduce: `python -m bench` (quick: 100 interactions, reports at 100,000 triples, both stores; 6 to 12",
        "minutes here) or `python -m bench --profile full` (1,000 interactions, reports at 100,000 and 1,000,000",
        "triples; add `--no-virtuoso` for the embedded store alone). `--save-figures` keeps what a run measured,",
        "`--from-figures` writes this page again from it, and `--add-reports-from` adds another run's report sizes.",
        "`--only SECTION` (small, robots, workers, steady, cumulative, reports, republish; repeatable) measures",
        "part of a profile, and `--report-sizes N …` sets the store sizes of the reports section.",
        "",
        *(line for note in getattr(f, "added_runs", []) for line in (note, "")),
    ]
    kept = kept_sections(path)
    path.write_text("\n".join(header + _sections(f) + kept) + "\n" + _own_commands(path), encoding="utf-8")


# A section another bench command writes (`<!-- section: name -->` … `<!-- /section: name -->`, e.g.
# bench/timeline.py's): kept as it is when this page is written again.
_KEPT = re.compile(r"<!-- section: (\S+) -->.*?<!-- /section: \1 -->", re.S)
OWN_COMMANDS = "## Measured by their own commands"


def kept_sections(path: Path) -> list[str]:
    """The marked sections above the page's last part (which `_own_commands` keeps whole)."""
    if not path.exists():
        return []
    text = path.read_text(encoding="utf-8").split("\n" + OWN_COMMANDS + "\n", 1)[0]
    return [line for match in _KEPT.finditer(text) for line in ("", match.group(0))]


def _own_commands(path: Path) -> str:
    """The page's last part, written from benches that run on their own (`python -m bench.people`): kept as it
    is when the sections above are written again."""
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    start = text.find("\n" + OWN_COMMANDS + "\n")
    return "" if start < 0 else text[start:]
