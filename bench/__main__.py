"""Run the benchmarks and write docs/performance.md.

    python -m bench                    # quick profile (6 to 12 minutes on 2 cores, both stores)
    python -m bench --profile full     # the issue's full sizes (1,000 interactions, reports at 1M triples)
    python -m bench --profile tiny --output /tmp/perf.md --no-virtuoso   # smoke run
    python -m bench --profile full --only reports --report-sizes 1000000 --output /tmp/perf.md  # one section

Servers run as separate processes (`segb serve --only api`, the naive baseline, Virtuoso) and are driven
over loopback HTTP, so the figures include the HTTP stack but never share an interpreter with the client.
"""

from __future__ import annotations

import argparse
import gc
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path

from bench.analysis import POSTGRES_LABEL
from bench.breakdown import breakdown
from bench.freshness import steady_lag
from bench.live import live_reports
from bench.measure import machine, peak_rss_mib
from bench.names import BASELINE, ONE_REPORT, VIRTUOSO_JOURNAL, VIRTUOSO_STORE
from bench.probes import ReadinessProbe
from bench.report import Figures, write_report
from bench.republish import Documents, republish_runs
from bench.republish import documents as republish_documents
from bench.runs import Cumulative, cumulative, journal_size, many_robots, small_posts, stored_triples
from bench.server import ROOT, baseline_server, null_server, python_path, segb_server
from bench.virtuoso import count_graph, measure_floor
from bench.workloads import cumulative_posts
from tests.support.postgres import PostgresProcess
from tests.support.robot_posts import LivePost, event_deltas, live_posts, ntriples_of, replicate
from tests.support.virtuoso import VirtuosoProcess

GRAPH = "http://amor-segb/events"
LIVE_RATE = 10.0  # posts per second of the robot publishing while reports are measured, and of the lag run


@dataclass(frozen=True)
class Profile:
    small_posts: int
    robots: int
    posts_per_robot: int
    interactions: int
    report_sizes: tuple[int, ...]
    report_repeats: int
    steady_seconds: float  # how long one robot posts at LIVE_RATE for the apply lag
    # Posts ready for the robot publishing while reports are measured: it stops when they run out, so enough for
    # a cold machine's Chromium and UI start-up before the watch begins (600 at LIVE_RATE is a minute).
    live_posts: int
    browser_seconds: float  # how long its conversations are watched in Chromium, before the pages are measured
    republish_sizes: tuple[int, ...]  # the tutorial robot's interactions before its re-publishes are measured


PROFILES = {
    "tiny": Profile(30, 4, 6, 8, (2_000,), 3, 2, 600, 2, (10, 40)),
    "quick": Profile(300, 16, 100, 100, (100_000,), 20, 20, 3_000, 10, (100, 1_000, 2_000)),
    "full": Profile(2_000, 16, 200, 1_000, (100_000, 1_000_000), 30, 20, 6_000, 10, (100, 1_000, 2_000)),
}
BREAKDOWN_POSTS = 300
SECTIONS = ("small", "robots", "workers", "steady", "cumulative", "reports", "republish")
# API processes (API_WORKERS) sharing one Virtuoso in the "workers" section, with the state in SQLite files
# (False) or in PostgreSQL (True, STATE_URL).
WORKER_RUNS = ((1, False), (2, False), (4, False), (2, True), (4, True))
TRIPLES_PER_INTERACTION = 151
INTERACTIONS_PER_COPY = 100


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--profile", choices=sorted(PROFILES), default="quick")
    parser.add_argument("--output", type=Path, default=Path(tempfile.gettempdir()) / "segb-bench.md")
    parser.add_argument("--no-virtuoso", action="store_true", help="only the embedded store")
    parser.add_argument("--code", default=code_version(), help="what code was measured, for the report's header")
    parser.add_argument("--save-figures", type=Path, help="also keep the measured figures in this file (pickle)")
    parser.add_argument("--from-figures", type=Path, help="measure nothing: write the report of saved figures")
    parser.add_argument(
        "--add-reports-from",
        type=Path,
        action="append",
        default=[],
        help="saved figures of another run whose report sizes this report lacks (say, 1M from a full run)",
    )
    parser.add_argument(
        "--only", choices=SECTIONS, action="append", help="measure only this section (repeatable; default: all)"
    )
    parser.add_argument(
        "--report-sizes", type=int, nargs="+", help="store sizes (triples) for the reports section, instead of the "
        "profile's"
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.from_figures:
        figures = pickle.loads(args.from_figures.read_bytes())  # only files this command wrote
    else:
        profile = PROFILES[args.profile]
        if args.report_sizes:
            profile = replace(profile, report_sizes=tuple(args.report_sizes))
        figures = measure(args.profile, profile, not args.no_virtuoso, frozenset(args.only or SECTIONS))
        figures.code = args.code
        figures.command = measuring_command(argv if argv is not None else sys.argv[1:])
    for path in args.add_reports_from:
        figures.add_reports(pickle.loads(path.read_bytes()))
    if args.save_figures:
        args.save_figures.write_bytes(pickle.dumps(figures))
    write_report(figures, args.output)
    print(figures.console_table())
    print(f"\nwrote {args.output} ({figures.wall_seconds:.0f} s)")
    return 0


@dataclass(frozen=True)
class Loads:
    """The payloads both stores receive, generated once."""

    deltas: list[str]
    robots: list[list[str]]
    live: list[LivePost]
    republish: list[Documents] = field(default_factory=list)

    @classmethod
    def of(cls, profile: Profile) -> Loads:
        robots = [event_deltas(profile.posts_per_robot, f"robot{i}") for i in range(profile.robots)]
        return cls(event_deltas(profile.small_posts), robots, live_posts(profile.live_posts))


def measure(name: str, profile: Profile, virtuoso: bool, sections: frozenset[str]) -> Figures:
    started = time.perf_counter()
    figures = Figures(profile=name, machine=machine(), virtuoso=virtuoso)
    # The bench's own garbage collector would pause its clients mid-request, and the pause would count in
    # whichever request was in flight: its full collections grow with what the bench holds (up to a second late
    # in a reports run, measured). It stays off while measuring; each server's start collects.
    gc.disable()
    try:
        _measure_all(profile, virtuoso, sections, figures)
    finally:
        gc.enable()
    figures.wall_seconds = time.perf_counter() - started
    figures.finished = datetime.now(UTC)
    figures.load_at_end = " / ".join(f"{load:.2f}" for load in os.getloadavg())
    return figures


def _measure_all(profile: Profile, virtuoso: bool, sections: frozenset[str], figures: Figures) -> None:
    with tempfile.TemporaryDirectory(prefix="segb-bench-") as scratch:
        root = Path(scratch)
        # The republish section makes its own documents: alone, it waits for no other section's payloads.
        loads = Loads([], [], []) if sections == {"republish"} else Loads.of(profile)
        runs = [run_embedded, run_virtuoso] if virtuoso else [run_embedded]
        if "republish" in sections:
            # Made before any server runs: the client's rdflib takes seconds a document at 2,000 interactions.
            loads = replace(loads, republish=list(republish_documents(profile.republish_sizes)))
        for run in runs:
            try:
                run(profile, loads, root, figures, sections)
            except Exception as error:  # the report still holds what was measured, and says what stopped
                traceback.print_exc()
                figures.failures.append(f"{run.__name__} stopped: {type(error).__name__}: {error}")


def run_embedded(profile: Profile, loads: Loads, root: Path, figures: Figures, sections: frozenset[str]) -> None:
    label = "embedded"
    deltas, robots = loads.deltas, loads.robots
    if "small" in sections:
        with null_server() as server:
            figures.client_floor = small_posts(server.url, deltas, "no-op server")
        with segb_server("oxigraph", root / "small") as server:
            figures.small[label] = small_posts(server.url, deltas, label)
        with segb_server("oxigraph", root / "quiet", {"LOGGING_LEVEL": "WARNING"}) as server:
            # What the INFO line per post (the request line) costs, by leaving it out.
            figures.small[f"{label}, LOGGING_LEVEL=WARNING"] = small_posts(server.url, deltas, f"{label}, quiet")
        with segb_server("oxigraph", root / "small-one", one_report(root)) as server:
            # The same server keeping one report current instead of six: what the reports' upkeep costs the posts.
            figures.small[ONE_REPORT] = small_posts(server.url, deltas, ONE_REPORT)
        # A few hundred posts are enough for in-process medians, and each costs the reports' upkeep too.
        figures.breakdown = breakdown(deltas[:BREAKDOWN_POSTS], root / "breakdown")
    if "robots" in sections:
        with segb_server("oxigraph", root / "robots") as server:
            count = lambda: stored_triples(server.url)  # noqa: E731
            figures.robots[label] = many_robots(server.url, robots, label, count, readiness=True)
        with segb_server("oxigraph", root / "robots-one", one_report(root)) as server:
            count = lambda: stored_triples(server.url)  # noqa: E731
            figures.robots[ONE_REPORT] = many_robots(server.url, robots, ONE_REPORT, count, readiness=True)
        with null_server() as server:
            figures.robots_floor = many_robots(server.url, robots, "no-op server", lambda: 0)
    if "steady" in sections:
        with segb_server("oxigraph", root / "steady", {"INGEST_ACK": "journal"}) as server:
            figures.steady[label] = steady_lag(server.url, deltas, LIVE_RATE, profile.steady_seconds)
    if "republish" in sections:
        figures.republish[label] = republish_runs(segb_server("oxigraph", root / "republish"), loads.republish)
    if "cumulative" in sections:
        with segb_server("oxigraph", root / "cumulative") as server:
            with ReadinessProbe(server.url, 0.02) as probe:
                run = cumulative(server.url, cumulative_posts(profile.interactions), label, profile.interactions)
            # Exported only once nothing else is in flight: see stored_triples.
            run.journal = journal_size(root / "cumulative", server.url, run.payload_bytes)
            figures.cumulative[label] = run
        figures.health_under_load = probe.latency()
    if "reports" not in sections:
        return
    for size in profile.report_sizes:
        data_dir = root / f"reports-{size}"
        files = write_dataset(root, size)
        load_seconds = segb_import("oxigraph", data_dir, files)
        with segb_server("oxigraph", data_dir) as server:
            measured = live_reports(server, count_lines(files), load_seconds, profile.report_repeats, loads.live,
                                    LIVE_RATE, profile.browser_seconds)  # fmt: skip
        figures.live[(label, size)] = measured
        figures.peak_rss_mib[(f"API process, {label}", size)] = measured.peak_rss_mib


def workers_label(workers: int, postgres: bool = False) -> str:
    return f"virtuoso, {workers} API worker{'s' if workers > 1 else ''}" + (f", {POSTGRES_LABEL}" if postgres else "")


def measuring_command(argv: list[str]) -> str:
    """The command line as far as it decides what is measured (not where figures and the report go)."""
    kept: list[str] = []
    skip = False
    for argument in argv:
        if skip:
            skip = False
        elif argument in ("--output", "--save-figures", "--code"):
            skip = True
        elif not argument.startswith(("--output=", "--save-figures=", "--code=")):
            kept.append(argument)
    return " ".join(["python -m bench", *kept])


def code_version() -> str:
    """The checkout's commit, and whether it had changes not committed yet."""
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=True).stdout.strip()  # fmt: skip
        changed = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain"], capture_output=True, text=True,
                                 check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return f"commit {commit}" + (" with uncommitted changes" if changed else "")


def one_report(root: Path) -> dict[str, str]:
    """Settings for a server keeping only the participants report current (a copy of the queries without the
    other reports)."""
    folder = root / "sparql-one-report"
    if not folder.exists():
        shutil.copytree(ROOT / "sparql", folder)
        for query in (folder / "reports").glob("*.rq"):
            if query.name != "participants.rq":
                query.unlink()
    return {"SPARQL_DIR": str(folder)}


def run_cumulative(url: str, data_dir: Path, interactions: int, label: str) -> Cumulative:
    run = cumulative(url, cumulative_posts(interactions), label, interactions)
    run.journal = journal_size(data_dir, url, run.payload_bytes)
    return run


def run_virtuoso(profile: Profile, loads: Loads, root: Path, figures: Figures, sections: frozenset[str]) -> None:
    label = "virtuoso"
    (root / "virtuoso").mkdir()
    virtuoso = VirtuosoProcess(root / "virtuoso")
    virtuoso.start()
    try:
        deltas, robots = loads.deltas, loads.robots

        def env(graph: str, **more: str) -> dict[str, str]:
            return {
                "VIRTUOSO_ENDPOINT": virtuoso.endpoint,
                "VIRTUOSO_USER": virtuoso.user,
                "VIRTUOSO_PASSWORD": virtuoso.password,
                "VIRTUOSO_GRAPH_URI": graph,
                **more,
            }

        # Each server has a data directory of its own: the journal there is the source of its graph.
        if "small" in sections:
            figures.virtuoso_floor = measure_floor(
                virtuoso, GRAPH + "/floor", event_deltas(min(200, len(deltas)), "floor")
            )
            with segb_server("virtuoso", root / "v-small", env(GRAPH + "/small")) as server:
                figures.small[VIRTUOSO_JOURNAL] = small_posts(server.url, deltas, VIRTUOSO_JOURNAL)
            with segb_server(
                "virtuoso", root / "v-small-store", env(GRAPH + "/small-store", INGEST_ACK="store")
            ) as server:
                figures.small[VIRTUOSO_STORE] = small_posts(server.url, deltas, VIRTUOSO_STORE)
            with baseline_server(virtuoso.endpoint, virtuoso.user, virtuoso.password, GRAPH + "/baseline") as naive:
                figures.small[BASELINE] = small_posts(naive.url, deltas, BASELINE)
        if "robots" in sections:
            with segb_server("virtuoso", root / "v-robots", env(GRAPH + "/robots")) as server:
                count = lambda: stored_triples(server.url)  # noqa: E731
                figures.robots[label] = many_robots(server.url, robots, label, count, readiness=True)
            naive_graph = GRAPH + "/baseline16"
            with baseline_server(virtuoso.endpoint, virtuoso.user, virtuoso.password, naive_graph) as naive:
                # The baseline has no export route: its graph is counted in Virtuoso itself.
                figures.robots[BASELINE] = many_robots(
                    naive.url, robots, BASELINE, lambda: count_graph(virtuoso, naive_graph)
                )
        if "workers" in sections:
            postgres = PostgresProcess()
            postgres.start()
            try:
                for workers, shared_state in WORKER_RUNS:
                    name = workers_label(workers, shared_state)
                    key = f"workers{workers}{'-pg' if shared_state else ''}"
                    state = {"STATE_URL": postgres.create_database(key.replace("-", "_"))} if shared_state else {}
                    settings = env(f"{GRAPH}/{key}", API_WORKERS=str(workers), **state)
                    with segb_server("virtuoso", root / f"v-{key}", settings) as one:
                        count = lambda: stored_triples(one.url)  # noqa: E731
                        figures.robots[name] = many_robots(one.url, robots, name, count, readiness=True)
            finally:
                postgres.remove()
        if "steady" in sections:
            with segb_server("virtuoso", root / "v-steady", env(GRAPH + "/steady", INGEST_ACK="journal")) as server:
                figures.steady[label] = steady_lag(server.url, deltas, LIVE_RATE, profile.steady_seconds)
        if "republish" in sections:
            server = segb_server("virtuoso", root / "v-republish", env(GRAPH + "/republish"))
            figures.republish[label] = republish_runs(server, loads.republish)
        if "cumulative" in sections:
            with segb_server("virtuoso", root / "v-cumulative", env(GRAPH + "/cumulative")) as server:
                figures.cumulative[label] = run_cumulative(
                    server.url, root / "v-cumulative", profile.interactions, label
                )
        if "reports" not in sections:
            return
        for size in profile.report_sizes:
            data_dir = root / f"v-reports-{size}"
            settings = env(f"{GRAPH}/reports{size}")
            files = write_dataset(root, size)
            # The import applies what it journals (INGEST_ACK=store), so the server starts on a loaded store.
            load_seconds = segb_import("virtuoso", data_dir, files, {**settings, "INGEST_ACK": "store"})
            with segb_server("virtuoso", data_dir, settings) as server:
                measured = live_reports(server, count_lines(files), load_seconds, profile.report_repeats,
                                        loads.live, LIVE_RATE, profile.browser_seconds)  # fmt: skip
            figures.live[(label, size)] = measured
            figures.peak_rss_mib[(f"API process, {label}", size)] = measured.peak_rss_mib
            figures.peak_rss_mib[("virtuoso-t (whole run so far)", size)] = _virtuoso_rss(virtuoso)
    finally:
        virtuoso.stop()


def _virtuoso_rss(virtuoso: VirtuosoProcess) -> float | None:
    process = virtuoso._process  # the test helper exposes no pid; the bench only reads /proc with it
    return peak_rss_mib(process.pid) if process is not None else None


def write_dataset(root: Path, size: int) -> list[Path]:
    """About `size` triples of emotion-mirror robots as N-Triples files (one per robot), cached per size."""
    folder = root / f"dataset-{size}"
    if folder.exists():
        return sorted(folder.glob("*.nt"))
    folder.mkdir()
    per_copy = INTERACTIONS_PER_COPY * TRIPLES_PER_INTERACTION
    if size < per_copy:
        texts = [ntriples_of(max(1, size // TRIPLES_PER_INTERACTION), "mirror")]
    else:
        texts = list(replicate(ntriples_of(INTERACTIONS_PER_COPY, "mirror"), round(size / per_copy)))
    for index, text in enumerate(texts):
        (folder / f"robot{index:03d}.nt").write_text(text, encoding="utf-8")
    return sorted(folder.glob("*.nt"))


def count_lines(files: list[Path]) -> int:
    """Triples in N-Triples files (one a line)."""
    total = 0
    for path in files:
        with path.open("rb") as file:
            total += sum(1 for line in file if line.strip())
    return total


def segb_import(store: str, data_dir: Path, files: list[Path], env: dict[str, str] | None = None) -> float:
    """`segb import` of the files before any server runs on `data_dir`; the seconds it took."""
    argv = ["-m", "segb_server.backend.cli", "import", "--store", store, "--data-dir", str(data_dir)]
    begin = time.perf_counter()
    subprocess.run(
        [sys.executable, *argv, *map(str, files)],
        check=True,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": python_path(), **(env or {})},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return time.perf_counter() - begin


if __name__ == "__main__":
    sys.exit(main())
