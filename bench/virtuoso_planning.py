"""What the views' keyed queries cost Virtuoso: planning a new text against running a planned one, by the number
of keys a query binds and by the length of one robot's history.

    python -m bench.virtuoso_planning                  # 1,000 visits, then 6,000 (about 4 minutes)
    python -m bench.virtuoso_planning --visits 300 --more 1000 --repeats 2

After each batch of posts, every kept view asks Virtuoso its query bound to the keys the batch touched (a
`VALUES` block of the batch's messages, activities, findings). The keys are new each time, so every such text
is new to Virtuoso, which plans it again; its SPARQL endpoint cannot be handed the keys beside a text that stays
the same. This bench separates the two costs. The server, in process against a Virtuoso fixture
(tests/support/virtuoso.py), keeps its views while one robot (bench/one_robot.py) logs `--visits` visits; the
keyed queries its views ask for one more visit are recorded; each is then asked with 1, 25 and 100 keys of
earlier visits, as new texts (keys no query named before: what a batch asks) and then as the same texts again
(their plans kept: what running them costs). Virtuoso's own CPU time (`/proc/<pid>/stat`, 10 ms ticks) is
summed over `--repeats` batches of every view's keyed query. Then the robot logs on to `--more` visits and the
same is measured again.

The difference is Virtuoso's planning, paid once per view and batch: a bigger batch pays it for more posts,
a longer history does not change it.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from itertools import islice
from pathlib import Path

from bench.measure import cpu_seconds, machine
from bench.one_robot import OneRobot, one_robot
from bench.views_cpu import post_in_process
from segb_server.backend.config import Settings
from segb_server.backend.services.container import Services, build_services
from segb_server.backend.store.base import Bindings, QueryResult
from segb_server.backend.store.virtuoso import VirtuosoStore
from tests.support.virtuoso import VirtuosoProcess

VISITS = 1000
MORE = 6000
REPEATS = 5
KEYS = (1, 25, 100)
THREADS = 4
# A keyed query's VALUES block of unit IRIs: `VALUES (?message) { (<…>) (<…>) }`, as the views bind it.
_UNITS = re.compile(r"VALUES \((\?\w+)\) \{ ((?:\(<[^>]*>\) ?)+)\}")


class _RecordingStore(VirtuosoStore):
    """The Virtuoso adapter, keeping the texts of the queries asked while `recorded` is a list."""

    recorded: list[str] | None = None

    def query(self, sparql: str, bindings: Bindings | None = None, timeout: float | None = None) -> QueryResult:
        if self.recorded is not None:
            self.recorded.append(sparql)
        return super().query(sparql, bindings, timeout)


@dataclass(frozen=True)
class Cost:
    history: int  # visits of the robot
    keys: int  # keys a query binds
    queries: int  # the keyed queries of one batch (one a view)
    new_cpu_ms: float  # Virtuoso's CPU for one batch's queries as new texts
    same_cpu_ms: float  # the same texts again
    new_wall_ms: float
    same_wall_ms: float

    @property
    def planning_share(self) -> float:
        return max(0.0, self.new_cpu_ms - self.same_cpu_ms) / self.new_cpu_ms if self.new_cpu_ms else 0.0


def keyed_queries(texts: list[str], visit: int) -> list[str]:
    """The recorded texts whose units are all keys of visit `visit` (the rest: lookups of classes, terms)."""
    return [text for text in texts if (units := _units(text)) and all(unit.endswith(f"_{visit}>") for unit in units)]


def _units(text: str) -> list[str]:
    found = _UNITS.search(text)
    return re.findall(r"<[^>]*>", found.group(2)) if found else []


def with_keys(text: str, visit: int, visits: list[int]) -> str:
    """`text` bound to the same units of each of `visits` instead of `visit`'s."""
    found = _UNITS.search(text)
    assert found is not None
    rows = [f"({unit.removesuffix(f'_{visit}>')}_{other}>)" for other in visits for unit in _units(text)]
    return text.replace(found.group(0), f"VALUES ({found.group(1)}) {{ {' '.join(rows)} }}", 1)


def measure(store: _RecordingStore, pid: int, queries: list[str], visit: int, history: int, repeats: int,
            unasked: Iterator[int]) -> list[Cost]:  # fmt: skip
    """Each view's query of `visit` bound to visits taken from `unasked` (each bound once: new texts)."""
    costs = []
    for keys in KEYS:
        batches = [list(islice(unasked, keys)) for _ in range(repeats)]  # a batch's keys, bound into each view's query
        assert all(len(batch) == keys for batch in batches), "too few earlier visits to bind"
        texts = [with_keys(text, visit, batch) for batch in batches for text in queries]
        timed = []
        for _ in ("new", "same"):
            began_cpu, began = cpu_seconds(pid), time.perf_counter()
            for text in texts:
                store.query(text)
            cpu, wall = cpu_seconds(pid) - began_cpu, time.perf_counter() - began
            timed.append((cpu * 1000 / repeats, wall * 1000 / repeats))
        (new_cpu, new_wall), (same_cpu, same_wall) = timed
        costs.append(Cost(history, keys, len(queries), new_cpu, same_cpu, new_wall, same_wall))
    return costs


def _log(services: Services, robot: OneRobot, start: int, end: int) -> None:
    with ThreadPoolExecutor(THREADS) as pool:
        last = max(pool.map(lambda index: post_in_process(services, robot.visit(index)), range(start, end)), default=0)
    assert services.writes.wait_viewed(last, 3600), "the views did not include the last post"


def run(visits: int, more: int, repeats: int, root: Path) -> list[Cost]:
    (root / "virtuoso").mkdir()
    (root / "data").mkdir()
    virtuoso = VirtuosoProcess(root / "virtuoso")
    virtuoso.start()
    try:
        settings = Settings(_env_file=None, store="virtuoso", data_dir=root / "data",  # type: ignore[call-arg]
                            virtuoso_endpoint=virtuoso.endpoint, virtuoso_user=virtuoso.user,
                            virtuoso_password=virtuoso.password)  # fmt: skip
        store = _RecordingStore(endpoint=virtuoso.endpoint, user=virtuoso.user, password=virtuoso.password,
                                graph_uri=settings.graph_uri)  # fmt: skip
        services = build_services(settings, store)
        services.start()
        robot = one_robot()
        costs: list[Cost] = []
        try:
            assert services.writes.wait_viewed(post_in_process(services, robot.first), 600), "the views were not built"
            _log(services, robot, 0, visits)
            store.recorded = []
            _log(services, robot, visits, visits + 1)  # one more visit: the views' queries for its keys
            queries = keyed_queries(store.recorded, visits)
            store.recorded = None
            assert queries, "the views asked no keyed query"
            # earlier visits, newest first
            costs += measure(store, virtuoso.pid, queries, visits, visits, repeats, iter(range(visits - 1, -1, -1)))
            _log(services, robot, visits + 1, more)
            costs += measure(store, virtuoso.pid, queries, visits, more, repeats, iter(range(more - 1, visits, -1)))
        finally:
            services.close()
            store.close()
        return costs
    finally:
        virtuoso.stop()


def markdown(costs: list[Cost], command: str) -> str:
    first = costs[0]
    lines = [
        f"`{command}`: the keyed queries of one batch (each kept view's, {first.queries} in all) asked of Virtuoso "
        "as new texts and then as the same texts again; Virtuoso's CPU and the wall time for one batch's queries, "
        "asked one after another. A batch of N keys a query is N visits' worth: its CPU a visit is what the views' "
        "keyed queries cost Virtuoso for each post at that batch size.",
        "",
        "| visits of the robot | keys a query | CPU ms, new texts | CPU ms, same texts | planning share | "
        "CPU ms a visit, new texts | wall ms, new texts | wall ms, same texts |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for cost in costs:
        lines.append(
            f"| {cost.history:,} | {cost.keys} | {cost.new_cpu_ms:.0f} | {cost.same_cpu_ms:.0f} | "
            f"{100 * cost.planning_share:.0f}% | {cost.new_cpu_ms / cost.keys:.1f} | {cost.new_wall_ms:.0f} | "
            f"{cost.same_wall_ms:.0f} |"
        )
    histories = sorted({cost.history for cost in costs})
    if len(histories) == 2:
        lines += ["", f"New texts at {histories[1]:,} visits against {histories[0]:,}:"]
        for keys in KEYS:
            before, after = (next(c for c in costs if c.history == h and c.keys == keys) for h in histories)
            ratio = after.new_cpu_ms / before.new_cpu_ms if before.new_cpu_ms else float("nan")
            lines.append(f"- {keys} key{'s' if keys > 1 else ''} a query: {ratio:.2f}x Virtuoso's CPU")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.virtuoso_planning", description=__doc__.split("\n\n")[0])
    parser.add_argument("--visits", type=int, default=VISITS, help="visits of the robot before the first measure")
    parser.add_argument("--more", type=int, default=MORE, help="visits in all before the second measure")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="batches of queries summed a figure")
    args = parser.parse_args(argv)
    needed = args.repeats * sum(KEYS)
    if args.visits < needed or args.more - args.visits - 1 < needed:
        parser.error(f"each history needs at least {needed} earlier visits to bind each key once")
    with tempfile.TemporaryDirectory(prefix="segb-virtuoso-planning-") as root:
        costs = run(args.visits, args.more, args.repeats, Path(root))
    defaults = (args.visits, args.more, args.repeats) == (VISITS, MORE, REPEATS)
    command = "python -m bench.virtuoso_planning" + (
        "" if defaults else f" --visits {args.visits} --more {args.more} --repeats {args.repeats}"
    )
    print(markdown(costs, command))
    print("\nmachine: " + "; ".join(f"{k} {v}" for k, v in machine().items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
