"""One robot, long history: what keeping the views current costs per post as one robot's history grows.

    python -m bench.long_history                      # 10k, 1M and 5M triples (about 25 minutes)
    python -m bench.long_history --sizes 10000 1000000

For each size, one robot's history (the receptionist of examples/receptionist.py: a new visitor each visit, the
robot's node gaining children with every one) is loaded into a fresh embedded store, the server's views are
built from it, and then 30 more visits are posted one at a time through the server's own write path (journal,
applier, views' keeper), in process. Each post is timed from the applier's write until every view includes it
(the views' keeper in its own thread, as `bench/breakdown.py` measures it), and its work is counted: the
store's queries and the rows they answered, and the SQLite steps of each view's database. Then the same for
the PyPI client's cumulative re-publish: the robot's whole graph of the last visits sent again with one new
visit, whose only new triples are that visit's.

The upkeep must not grow with the history: the ratios against the smallest size are printed beside each row.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pyoxigraph import RdfFormat

from bench.measure import machine
from bench.one_robot import SECONDS_PER_VISIT, OneRobot, one_robot
from segb_server.backend.config import Settings
from segb_server.backend.services.container import Services, build_services
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.services.upkeep.keeper import MAX_REST_SECONDS
from segb_server.backend.store.factory import open_store
from segb_server.backend.store.oxigraph import OxigraphStore

SIZES = (10_000, 1_000_000, 5_000_000)
POSTS = 30
CUMULATIVE_VISITS = 200  # visits a cumulative re-publish sends again with its new one
LOAD_VISITS = 20_000  # visits per bulk-loaded chunk
STEPS_PER_TICK = 1000


@dataclass
class Work:
    queries: int = 0
    ticks: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class SizeFigures:
    triples: int
    load_seconds: float
    build_seconds: float
    delta_ms: list[float]
    cumulative_ms: list[float]
    queries_per_post: float
    steps_per_post: dict[str, float]
    disk_mib: dict[str, float]

    @property
    def delta_p50(self) -> float:
        return statistics.median(self.delta_ms)

    @property
    def cumulative_p50(self) -> float:
        return statistics.median(self.cumulative_ms)


class CountingStore(OxigraphStore):
    """The embedded store, counting the queries the views ask (the rows they read: tests/services/
    test_upkeep_work.py, which can afford to ask each query twice)."""

    def __init__(self, graph_uri: str, path: Path) -> None:
        super().__init__(graph_uri, path)
        self.work = Work()

    def query(self, sparql: str, bindings: Any = None, timeout: float | None = None) -> Any:
        if threading.current_thread().name.startswith("segb-view"):
            self.work.queries += 1
        return super().query(sparql, bindings, timeout)


def measure_size(robot: OneRobot, triples: int, root: Path) -> SizeFigures:
    visits = max(1, (triples - len(robot.first.splitlines())) // len(robot.visit(0).splitlines()))
    data_dir = root / f"size-{triples}"
    settings = Settings(_env_file=None, store="oxigraph", data_dir=data_dir)  # type: ignore[call-arg]
    store = CountingStore(settings.graph_uri, data_dir / "oxigraph")
    began = time.perf_counter()
    store._store.bulk_load((robot.first + "\n").encode(), RdfFormat.N_TRIPLES)
    for start in range(0, visits, LOAD_VISITS):
        chunk = robot.history(min(LOAD_VISITS, visits - start), start)
        store._store.bulk_load(chunk.encode(), RdfFormat.N_TRIPLES)
    load_seconds = time.perf_counter() - began
    services = build_services(settings, store)
    ticks = _watch_views(services)
    began = time.perf_counter()
    services.start()
    assert services.writes.wait_viewed(0, 7200), "the views were not built"
    build_seconds = time.perf_counter() - began
    try:
        store.work = Work()
        for name in ticks:
            ticks[name] = 0
        delta_ms = [_upkeep_ms(services, robot.visit(visits + n)) for n in range(POSTS)]
        work = Work(store.work.queries, dict(ticks))
        cumulative_ms = []
        for n in range(POSTS):
            index = visits + POSTS + n
            payload = robot.history(CUMULATIVE_VISITS, index - CUMULATIVE_VISITS) + robot.visit(index)
            cumulative_ms.append(_upkeep_ms(services, payload))
    finally:
        services.close()
        store.close()
    return SizeFigures(
        triples=_triples(data_dir),
        load_seconds=load_seconds,
        build_seconds=build_seconds,
        delta_ms=delta_ms,
        cumulative_ms=cumulative_ms,
        queries_per_post=work.queries / POSTS,
        steps_per_post={name: STEPS_PER_TICK * count / POSTS for name, count in work.ticks.items()},
        disk_mib=_disk(data_dir),
    )


def _watch_views(services: Services) -> dict[str, int]:
    """Count the SQLite steps of each view's database (its writer's connection)."""
    ticks = {"reports": 0, "graph": 0}
    databases = {"reports": services.reports.change_log().db if services.reports.served_by_rows() else None,
                 "graph": services.graph.index.db}  # fmt: skip
    for name, database in databases.items():
        if database is not None:
            database.writer().set_progress_handler(_counter(ticks, name), STEPS_PER_TICK)
    return ticks


def _counter(ticks: dict[str, int], name: str) -> Any:
    def tick() -> int:
        ticks[name] += 1
        return 0

    return tick


def _upkeep_ms(services: Services, payload: str) -> float:
    """One post through the write path; from its write to the store until every view includes it. Posted once
    the views' keeper has rested after the last one (`MAX_REST_SECONDS`): the time is then the post's own
    upkeep, not the rest the keeper takes between batches under a stream of posts."""
    time.sleep(MAX_REST_SECONDS + 0.05)
    result = services.ingest.ingest(RdfPayload(payload.encode(), RdfFormat.N_TRIPLES, claimed_user=None), actor="bench")
    applied = time.perf_counter()
    assert services.writes.wait_viewed(result.sequence, 600), "the views did not include the post"
    return (time.perf_counter() - applied) * 1000


def _triples(data_dir: Path) -> int:
    store = open_store(Settings(_env_file=None, store="oxigraph", data_dir=data_dir))  # type: ignore[call-arg]
    try:
        return store.count()
    finally:
        store.close()


def _disk(data_dir: Path) -> dict[str, float]:
    def size(path: Path) -> float:
        if path.is_dir():
            return sum(item.stat().st_size for item in path.rglob("*") if item.is_file()) / 2**20
        return path.stat().st_size / 2**20 if path.exists() else 0.0

    views = {
        name: size(data_dir / name) + size(data_dir / f"{name}-wal") for name in ("reports.sqlite3", "graph.sqlite3")
    }
    return {"store": size(data_dir / "oxigraph"), **views}


def markdown(figures: list[SizeFigures], command: str) -> str:
    base = figures[0]
    lines = [
        f"`{command}`: one robot's history loaded, the views built from it, then {POSTS} posts of one visit each "
        f"(56 triples) and {POSTS} cumulative re-publishes ({CUMULATIVE_VISITS} visits sent again with a new one), "
        "one at a time; upkeep is from the post's write to the store until every view includes it.",
        "",
        "| history (triples) | load s | views built s | upkeep p50 ms (ratio) | cumulative p50 ms (ratio) "
        "| store queries / post | SQLite steps / post (reports, graph) | store / views on disk MiB |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for size in figures:
        views = sum(value for name, value in size.disk_mib.items() if name != "store")
        lines.append(
            f"| {size.triples:,} | {size.load_seconds:.0f} | {size.build_seconds:.0f} | "
            f"{size.delta_p50:.1f} ({size.delta_p50 / base.delta_p50:.2f}x) | "
            f"{size.cumulative_p50:.1f} ({size.cumulative_p50 / base.cumulative_p50:.2f}x) | "
            f"{size.queries_per_post:.1f} | "
            f"{size.steps_per_post.get('reports', 0):,.0f}, {size.steps_per_post.get('graph', 0):,.0f} | "
            f"{size.disk_mib['store']:.0f} / {views:.0f} |"
        )
    return "\n".join(lines)


@contextmanager
def _quiet_collector() -> Iterator[None]:
    gc.collect()
    gc.disable()  # a full collection in the middle of a post would be counted as its upkeep
    try:
        yield
    finally:
        gc.enable()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.long_history", description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), help="history sizes in triples")
    args = parser.parse_args(argv)
    robot = one_robot()
    figures = []
    with tempfile.TemporaryDirectory(prefix="segb-long-history-") as root, _quiet_collector():
        for size in args.sizes:
            figures.append(measure_size(robot, size, Path(root)))
            print(f"  {size:,} triples: upkeep p50 {figures[-1].delta_p50:.1f} ms", file=sys.stderr, flush=True)
    command = "python -m bench.long_history" + (
        "" if args.sizes == list(SIZES) else f" --sizes {' '.join(map(str, args.sizes))}"
    )
    print(markdown(figures, command))
    print(f"\nvisits {SECONDS_PER_VISIT} s apart in the log's own time; machine: "
          + "; ".join(f"{k} {v}" for k, v in machine().items()))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
