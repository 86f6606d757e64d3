"""One robot, long history: what keeping the views current costs per post as one robot's history grows.

    python -m bench.long_history                      # 10k, 1M and 5M triples (about 25 minutes)
    python -m bench.long_history --sizes 10000 1000000

For each size, one robot's history (the receptionist of examples/receptionist.py: a new visitor each visit, the
robot's node gaining children with every one) is loaded into a fresh embedded store and the server's views are
built from it. Then 60 more visits are posted one at a time through the server's own write path (journal,
applier, views' keeper), in process, the sizes taking turns post by post. Each post is timed from the applier's
write until every view includes it (the views' keeper in its own thread, as `bench/breakdown.py` measures it),
and its work is counted: the store's queries and the rows they answered, and the SQLite steps of each view's
database. Then the same for the PyPI client's cumulative re-publish: the robot's whole graph of the last visits
sent again with one new visit, whose only new triples are that visit's.

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
from segb_server.backend.services.container import VIEW_FILES, Services, build_services
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.services.views.keeper import MAX_REST_SECONDS
from segb_server.backend.store.factory import open_store
from segb_server.backend.store.oxigraph import OxigraphStore

SIZES = (10_000, 1_000_000, 5_000_000)
POSTS = 60  # per size: a median of 30 moved by up to a fifth between runs of the same code
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


class History:
    """One size: a robot's history loaded into its own store, its server's services built and started on it, and
    what its posts measured. Every size stays open while the others are measured: their posts alternate, so a
    drift of the machine's speed (a shared virtual machine's) weighs on every size alike."""

    def __init__(self, robot: OneRobot, triples: int, root: Path) -> None:
        self.robot = robot
        self.visits = max(1, (triples - len(robot.first.splitlines())) // len(robot.visit(0).splitlines()))
        self.data_dir = root / f"size-{triples}"
        settings = Settings(_env_file=None, store="oxigraph", data_dir=self.data_dir)  # type: ignore[call-arg]
        self.store = CountingStore(settings.graph_uri, self.data_dir / "oxigraph")
        began = time.perf_counter()
        self.store._store.bulk_load((robot.first + "\n").encode(), RdfFormat.N_TRIPLES)
        for start in range(0, self.visits, LOAD_VISITS):
            chunk = robot.history(min(LOAD_VISITS, self.visits - start), start)
            self.store._store.bulk_load(chunk.encode(), RdfFormat.N_TRIPLES)
        self.load_seconds = time.perf_counter() - began
        self.services = build_services(settings, self.store)
        self.ticks = _watch_views(self.services)
        began = time.perf_counter()
        self.services.start()
        assert self.services.writes.wait_viewed(0, 7200), "the views were not built"
        self.build_seconds = time.perf_counter() - began
        self.store.work = Work()
        for name in self.ticks:
            self.ticks[name] = 0
        self.delta_ms: list[float] = []
        self.cumulative_ms: list[float] = []
        self.work = Work()

    def post_visit(self, n: int) -> None:
        """The n-th post of one new visit; the work of these posts is what is counted."""
        self.delta_ms.append(_upkeep_ms(self.services, self.robot.visit(self.visits + n)))
        self.work = Work(self.store.work.queries, dict(self.ticks))

    def post_cumulative(self, n: int) -> None:
        """The n-th cumulative re-publish: the last visits sent again with a new one."""
        index = self.visits + POSTS + n
        payload = self.robot.history(CUMULATIVE_VISITS, index - CUMULATIVE_VISITS) + self.robot.visit(index)
        self.cumulative_ms.append(_upkeep_ms(self.services, payload))

    def close(self) -> SizeFigures:
        self.services.close()
        self.store.close()
        return SizeFigures(
            triples=_triples(self.data_dir),
            load_seconds=self.load_seconds,
            build_seconds=self.build_seconds,
            delta_ms=self.delta_ms,
            cumulative_ms=self.cumulative_ms,
            queries_per_post=self.work.queries / POSTS,
            steps_per_post={name: STEPS_PER_TICK * count / POSTS for name, count in self.work.ticks.items()},
            disk_mib=_disk(self.data_dir),
        )


def measure(robot: OneRobot, sizes: list[int], root: Path) -> list[SizeFigures]:
    """Every size loaded and built, then their posts in turns: one visit each, then one re-publish each."""
    histories: list[History] = []
    try:
        for size in sizes:
            histories.append(History(robot, size, root))
            print(f"  {size:,} triples: loaded and built", file=sys.stderr, flush=True)
        for n in range(POSTS):
            for history in histories:
                history.post_visit(n)
        for n in range(POSTS):
            for history in histories:
                history.post_cumulative(n)
    finally:
        figures = [history.close() for history in histories]
    return figures


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

    views = {name: size(data_dir / name) + size(data_dir / f"{name}-wal") for name in VIEW_FILES}
    return {"store": size(data_dir / "oxigraph"), **views}


def markdown(figures: list[SizeFigures], command: str) -> str:
    base = figures[0]
    lines = [
        f"`{command}`: one robot's history loaded, the views built from it, then {POSTS} posts of one visit each "
        f"(56 triples) and {POSTS} cumulative re-publishes ({CUMULATIVE_VISITS} visits sent again with a new one), "
        "one at a time, the sizes taking turns; upkeep is from the post's write to the store until every view includes "
        "it.",
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
    with tempfile.TemporaryDirectory(prefix="segb-long-history-") as root, _quiet_collector():
        figures = measure(robot, args.sizes, Path(root))
    command = "python -m bench.long_history" + (
        "" if args.sizes == list(SIZES) else f" --sizes {' '.join(map(str, args.sizes))}"
    )
    print(markdown(figures, command))
    print(f"\nvisits {SECONDS_PER_VISIT} s apart in the log's own time; machine: "
          + "; ".join(f"{k} {v}" for k, v in machine().items()))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
