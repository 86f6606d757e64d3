"""Run the benchmarks and write docs/performance.md.

    python -m bench                    # quick profile (about 2 minutes on 2 cores)
    python -m bench --profile full     # the issue's full sizes (1,000 interactions, 1M triples)
    python -m bench --profile tiny --output /tmp/perf.md --no-virtuoso   # smoke run

Servers run as separate processes (`segb serve --only api`, the naive baseline, Virtuoso) and are driven
over loopback HTTP, so the figures include the HTTP stack but never share an interpreter with the client.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import httpx

from bench.breakdown import breakdown
from bench.measure import Latency, machine, peak_rss_mib
from bench.report import Figures, write_report
from bench.runs import cumulative, exported_triples, many_robots, probe_health, report_queries, small_posts
from bench.server import baseline_server, null_server, segb_server
from bench.virtuoso import count_graph, measure_floor
from bench.workloads import cumulative_posts, event_deltas, ntriples_of, replicate
from tests.support.virtuoso import VirtuosoProcess

GRAPH = "http://amor-segb/events"


@dataclass(frozen=True)
class Profile:
    small_posts: int
    robots: int
    posts_per_robot: int
    interactions: int
    report_sizes: tuple[int, ...]
    report_repeats: int
    virtuoso_report_repeats: int  # its reports take up to seconds each: fewer repeats keep the run short


PROFILES = {
    "tiny": Profile(30, 4, 6, 8, (2_000,), 3, 3),
    "quick": Profile(300, 16, 30, 100, (10_000, 100_000), 20, 3),
    "full": Profile(2_000, 16, 200, 1_000, (10_000, 100_000, 1_000_000), 30, 10),
}
TRIPLES_PER_INTERACTION = 151
INTERACTIONS_PER_COPY = 100


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--profile", choices=sorted(PROFILES), default="quick")
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parents[1] / "docs/performance.md")
    parser.add_argument("--no-virtuoso", action="store_true", help="only the embedded store")
    args = parser.parse_args(argv)
    profile = PROFILES[args.profile]
    started = time.perf_counter()
    figures = Figures(profile=args.profile, machine=machine())
    with tempfile.TemporaryDirectory(prefix="segb-bench-") as scratch:
        root = Path(scratch)
        loads = Loads.of(profile)
        run_embedded(profile, loads, root, figures)
        if not args.no_virtuoso:
            run_virtuoso(profile, loads, root, figures)
    figures.wall_seconds = time.perf_counter() - started
    write_report(figures, args.output)
    print(figures.console_table())
    print(f"\nwrote {args.output} ({figures.wall_seconds:.0f} s)")
    return 0


@dataclass(frozen=True)
class Loads:
    """The payloads both stores receive, generated once."""

    deltas: list[str]
    robots: list[list[str]]

    @classmethod
    def of(cls, profile: Profile) -> Loads:
        robots = [event_deltas(profile.posts_per_robot, f"robot{i}") for i in range(profile.robots)]
        return cls(event_deltas(profile.small_posts), robots)


def run_embedded(profile: Profile, loads: Loads, root: Path, figures: Figures) -> None:
    label = "embedded"
    deltas, robots = loads.deltas, loads.robots
    with null_server() as server:
        figures.client_floor = small_posts(server.url, deltas, "no-op server")
    with segb_server("oxigraph", root / "small") as server:
        figures.small[label] = small_posts(server.url, deltas, label)
    with segb_server("oxigraph", root / "quiet", {"LOGGING_LEVEL": "WARNING"}) as server:
        # What the two INFO lines per post (request and ingest) cost, by leaving them out.
        figures.small[f"{label}, LOGGING_LEVEL=WARNING"] = small_posts(server.url, deltas, f"{label}, quiet")
    figures.breakdown = breakdown(deltas, root / "breakdown")
    with segb_server("oxigraph", root / "robots") as server:
        figures.robots[label] = many_robots(server.url, robots, label, lambda: exported_triples(server.url))
    with null_server() as server:
        figures.robots_floor = many_robots(server.url, robots, "no-op server", lambda: 0)
    with segb_server("oxigraph", root / "cumulative") as server:
        stop = threading.Event()
        health: list[float] = []
        prober = threading.Thread(target=lambda: health.extend(probe_health(server.url, stop)))
        prober.start()
        try:
            posts = cumulative_posts(profile.interactions)
            figures.cumulative[label] = cumulative(server.url, posts, label, profile.interactions)
        finally:
            stop.set()
            prober.join()
        figures.health_under_load = Latency.of(health)
    for size in profile.report_sizes:
        data_dir = root / f"reports-{size}"
        files = write_dataset(root, size)
        segb_import(data_dir, files)
        with segb_server("oxigraph", data_dir) as server:
            figures.reports[(label, size)] = report_queries(server.url, profile.report_repeats, f"{label} {size}")
            figures.peak_rss_mib[(f"API process, {label}", size)] = server.peak_rss_mib


def run_virtuoso(profile: Profile, loads: Loads, root: Path, figures: Figures) -> None:
    label = "virtuoso"
    (root / "virtuoso").mkdir()
    virtuoso = VirtuosoProcess(root / "virtuoso")
    virtuoso.start()
    try:
        deltas, robots = loads.deltas, loads.robots

        def env(graph: str) -> dict[str, str]:
            return {
                "VIRTUOSO_ENDPOINT": virtuoso.endpoint,
                "VIRTUOSO_USER": virtuoso.user,
                "VIRTUOSO_PASSWORD": virtuoso.password,
                "VIRTUOSO_GRAPH_URI": graph,
            }

        figures.virtuoso_floor = measure_floor(virtuoso, GRAPH + "/floor", event_deltas(min(200, len(deltas)), "floor"))
        with segb_server("virtuoso", root / "v", env(GRAPH + "/small")) as server:
            figures.small[label] = small_posts(server.url, deltas, label)
        with baseline_server(virtuoso.endpoint, virtuoso.user, virtuoso.password, GRAPH + "/baseline") as naive:
            figures.small["naive baseline"] = small_posts(naive.url, deltas, "naive baseline")
        with segb_server("virtuoso", root / "v", env(GRAPH + "/robots")) as server:
            figures.robots[label] = many_robots(server.url, robots, label, lambda: exported_triples(server.url))
        naive_graph = GRAPH + "/baseline16"
        with baseline_server(virtuoso.endpoint, virtuoso.user, virtuoso.password, naive_graph) as naive:
            # The baseline has no export route: its graph is counted in Virtuoso itself.
            figures.robots["naive baseline"] = many_robots(
                naive.url, robots, "naive baseline", lambda: count_graph(virtuoso, naive_graph)
            )
        with segb_server("virtuoso", root / "v", env(GRAPH + "/cumulative")) as server:
            posts = cumulative_posts(profile.interactions)
            figures.cumulative[label] = cumulative(server.url, posts, label, profile.interactions)
        for size in profile.report_sizes:
            with segb_server("virtuoso", root / "v", env(f"{GRAPH}/reports{size}")) as server:
                for path in write_dataset(root, size):
                    post_ntriples(server.url, path)
                repeats = profile.virtuoso_report_repeats
                figures.reports[(label, size)] = report_queries(server.url, repeats, f"{label} {size}")
                figures.peak_rss_mib[(f"API process, {label}", size)] = server.peak_rss_mib
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


def segb_import(data_dir: Path, files: list[Path]) -> None:
    import subprocess

    from bench.server import ROOT

    subprocess.run(
        [
            sys.executable,
            "-m",
            "segb_server.backend.cli",
            "import",
            "--store",
            "oxigraph",
            "--data-dir",
            str(data_dir),
            *map(str, files),
        ],
        check=True,
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def post_ntriples(url: str, path: Path, chunk_lines: int = 50_000) -> None:
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    with httpx.Client(base_url=url, timeout=600) as client:
        for start in range(0, len(lines), chunk_lines):
            client.post(
                "/ttl",
                content="".join(lines[start : start + chunk_lines]).encode(),
                headers={"Content-Type": "application/n-triples"},
            ).raise_for_status()


if __name__ == "__main__":
    sys.exit(main())
