"""One robot, posting without pause: what each kept view costs in CPU per post, and what the views cost ingest.

    python -m bench.views_cpu                       # 3 rounds of 2,500 posts, views on then off (about 6 minutes)
    python -m bench.views_cpu --posts 500 --rounds 1
    python -m bench.views_cpu --store virtuoso      # against a Virtuoso fixture started each round

In process, no HTTP (the soak, `bench/soak.py`, measures the same over HTTP with an auditor reading): the visits
of one robot (bench/one_robot.py) are posted by 4 threads through the server's own ingest service — journal,
applier, the views' keeper — as fast as each is answered, into a fresh embedded store; once with every view kept
and once with the views off (`KEEP_VIEWS=false`), round after round, so both see the machine alike. The clock
stops once the views include the last post.

Each view's updates are timed by their worker thread's CPU clock (`ViewKeeper.view_times`): the table says
which views cost most. The process's CPU per post, views on and off, is the budget: the views' Python and the
posts' take turns on one interpreter, and however the work is spread, N cores cannot answer more than
N * 1000 / (CPU ms per post) posts a second.

With `--store virtuoso` each round gets a Virtuoso of its own (tests/support/virtuoso.py), and Virtuoso's CPU
a post (`/proc/<pid>/stat`) is told beside the process's: there the views' cost is split between their Python
and the queries they ask the store.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from pyoxigraph import RdfFormat

from bench.measure import cpu_seconds, machine
from bench.one_robot import OneRobot, one_robot
from segb_server.backend.collector import tune_collector
from segb_server.backend.config import Settings
from segb_server.backend.services.container import Services, build_services
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.store.factory import open_store
from tests.support.virtuoso import VirtuosoProcess

POSTS = 2500
ROUNDS = 3
THREADS = 4


@dataclass(frozen=True)
class Round:
    views: bool
    posts: int
    seconds: float  # from the first post until the views include the last
    cpu_seconds: float  # the process's, over the same time
    view_cpu: dict[str, float]  # each view's CPU seconds
    view_wall: dict[str, float]
    batches: int
    store_cpu_seconds: float = 0.0  # a Virtuoso fixture's, over the same time (0 on the embedded store)

    @property
    def posts_per_second(self) -> float:
        return self.posts / self.seconds

    @property
    def cpu_ms_per_post(self) -> float:
        return 1000 * self.cpu_seconds / self.posts

    @property
    def store_cpu_ms_per_post(self) -> float:
        return 1000 * self.store_cpu_seconds / self.posts

    @property
    def views_cpu_ms_per_post(self) -> float:
        return 1000 * sum(self.view_cpu.values()) / self.posts


def run_round(robot: OneRobot, posts: int, views: bool, root: Path, store_kind: str = "oxigraph") -> Round:
    data_dir = Path(tempfile.mkdtemp(prefix="round-", dir=root))
    if store_kind == "virtuoso":
        (data_dir / "virtuoso").mkdir()
        virtuoso = VirtuosoProcess(data_dir / "virtuoso")
        virtuoso.start()
        try:
            settings = Settings(_env_file=None, store="virtuoso", data_dir=data_dir, keep_views=views,  # type: ignore[call-arg]
                                virtuoso_endpoint=virtuoso.endpoint, virtuoso_user=virtuoso.user,
                                virtuoso_password=virtuoso.password)  # fmt: skip
            return _timed_round(robot, posts, settings, virtuoso.pid)
        finally:
            virtuoso.stop()
    settings = Settings(_env_file=None, store="oxigraph", data_dir=data_dir, keep_views=views)  # type: ignore[call-arg]
    return _timed_round(robot, posts, settings, None)


def _timed_round(robot: OneRobot, posts: int, settings: Settings, store_pid: int | None) -> Round:
    store = open_store(settings)
    services = build_services(settings, store)
    services.start()
    try:
        first = post_in_process(services, robot.first)
        assert services.writes.wait_viewed(first, 600), "the views were not built"
        keeper = services.writes.keeper
        spent_before = keeper.progress.view_times()
        store_cpu = cpu_seconds(store_pid) if store_pid is not None else 0.0
        began, cpu = time.perf_counter(), time.process_time()
        with ThreadPoolExecutor(THREADS) as pool:
            last = max(pool.map(lambda index: post_in_process(services, robot.visit(index)), range(posts)))
        assert services.writes.wait_viewed(last, 600), "the views did not include the last post"
        seconds, cpu_seconds_spent = time.perf_counter() - began, time.process_time() - cpu
        store_cpu = cpu_seconds(store_pid) - store_cpu if store_pid is not None else 0.0
        spent = keeper.progress.view_times()
    finally:
        services.close()
        store.close()
    return Round(
        views=settings.keep_views,
        posts=posts,
        seconds=seconds,
        cpu_seconds=cpu_seconds_spent,
        view_cpu={name: spent[name].cpu - spent_before[name].cpu for name in spent},
        view_wall={name: spent[name].wall - spent_before[name].wall for name in spent},
        batches=max((spent[name].batches - spent_before[name].batches for name in spent), default=0),
        store_cpu_seconds=store_cpu,
    )


def post_in_process(services: Services, payload: str) -> int:
    """One post through the server's own ingest service (no HTTP): its journal sequence."""
    result = services.ingest.ingest(RdfPayload(payload.encode(), RdfFormat.N_TRIPLES, claimed_user=None), actor="bench")
    return result.sequence


def markdown(rounds: list[Round], command: str, virtuoso: bool = False) -> str:
    on = [r for r in rounds if r.views]
    off = [r for r in rounds if not r.views]
    rate_on = statistics.median(r.posts_per_second for r in on)
    rate_off = statistics.median(r.posts_per_second for r in off)
    cpu_on = statistics.median(r.cpu_ms_per_post for r in on)
    cpu_off = statistics.median(r.cpu_ms_per_post for r in off)
    views_cpu = statistics.median(r.views_cpu_ms_per_post for r in on)
    store_on = statistics.median(r.store_cpu_ms_per_post for r in on)
    store_off = statistics.median(r.store_cpu_ms_per_post for r in off)
    cores = os.cpu_count() or 1
    lines = [
        f"`{command}`: {on[0].posts:,} visits of one robot posted by {THREADS} threads through the ingest service "
        f"(in process, no HTTP), until the views include the last; {len(on)} round(s) each way, medians.",
        "",
        "| | views on | views off | on ÷ off |",
        "|---|--:|--:|--:|",
        f"| posts/s | {rate_on:.0f} | {rate_off:.0f} | {rate_on / rate_off:.2f} |",
        f"| process CPU ms / post | {cpu_on:.2f} | {cpu_off:.2f} | {cpu_on / cpu_off:.2f} |",
        f"| of which the views' updates (their threads' CPU) | {views_cpu:.2f} | 0 | |",
        *(
            [
                f"| Virtuoso's CPU ms / post | {store_on:.2f} | {store_off:.2f} | "
                f"{store_on / store_off if store_off else 0:.2f} |",
                f"| most posts/s {cores} cores could answer, Virtuoso's CPU included | "
                f"{cores * 1000 / (cpu_on + store_on):.0f} | {cores * 1000 / (cpu_off + store_off):.0f} | |",
            ]
            if virtuoso
            else []
        ),
        f"| most posts/s {cores} cores could answer at that CPU a post | {cores * 1000 / cpu_on:.0f} | "
        f"{cores * 1000 / cpu_off:.0f} | |",
        "",
        f"Each view, views on (batches per round: {', '.join(str(r.batches) for r in on)}):",
        "",
        "| view | CPU ms / post | wall ms / post | share of the views' CPU |",
        "|---|--:|--:|--:|",
    ]
    names = sorted(on[0].view_cpu, key=lambda name: -statistics.median(r.view_cpu[name] for r in on))
    for name in names:
        cpu = statistics.median(1000 * r.view_cpu[name] / r.posts for r in on)
        wall = statistics.median(1000 * r.view_wall[name] / r.posts for r in on)
        lines.append(f"| {name} | {cpu:.3f} | {wall:.3f} | {100 * cpu / views_cpu:.1f}% |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.views_cpu", description=__doc__.split("\n\n")[0])
    parser.add_argument("--posts", type=int, default=POSTS, help="visits posted a round")
    parser.add_argument("--rounds", type=int, default=ROUNDS, help="rounds each way (views on, then off)")
    parser.add_argument("--store", choices=("oxigraph", "virtuoso"), default="oxigraph")
    args = parser.parse_args(argv)
    robot = one_robot()
    tune_collector()  # as `segb serve` runs its processes
    rounds: list[Round] = []
    with tempfile.TemporaryDirectory(prefix="segb-views-cpu-") as root:
        for number in range(args.rounds):
            for views in (True, False):
                rounds.append(run_round(robot, args.posts, views, Path(root), args.store))
                last = rounds[-1]
                print(f"  round {number + 1}, views {'on' if views else 'off'}: {last.posts_per_second:.0f} posts/s, "
                      f"{last.cpu_ms_per_post:.2f} CPU ms a post", file=sys.stderr, flush=True)  # fmt: skip
    defaults = args.posts == POSTS and args.rounds == ROUNDS
    command = "python -m bench.views_cpu" + ("" if defaults else f" --posts {args.posts} --rounds {args.rounds}")
    command += "" if args.store == "oxigraph" else f" --store {args.store}"
    print(markdown(rounds, command, virtuoso=args.store == "virtuoso"))
    print("\nmachine: " + "; ".join(f"{k} {v}" for k, v in machine().items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
