"""This tree against an earlier commit, posted to alike, in turns: what a change gave, measured on one machine.

    python -m bench.versions --against f77806e                 # 3 rounds, 35 s each way, every view kept
    python -m bench.versions --against HEAD~3 --views off      # the views off (`KEEP_VIEWS=false`)
    python -m bench.versions --against f77806e --seconds 60 --rounds 5

This machine's speed drifts by some 15% within an hour (docs/performance.md#how-to-read-these-figures): the same
commit posted 206 times a second at one moment and 174 forty minutes later. Two versions measured one after the
other then differ by the drift as much as by the change. Here they take turns instead, in the order A B B A,
A B B A, … so that a drift within a round weighs on both alike, and the table gives every run and the medians.

Each run is `segb serve --only api` on a fresh embedded store, the soak's posting (bench/soak.py: 4 client
threads posting one robot's visits as fast as answered, no auditor), timed over `--seconds` after 5 s of warm-up,
with the CPU a post of the API process, of its children (the views' process) and of the clients. The earlier
commit runs from its files (`git archive`) in a temporary folder; its server imports the package from there
(checked before the first run).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from bench.client import Client
from bench.measure import cpu_seconds, machine
from bench.one_robot import OneRobot, one_robot
from bench.server import ROOT, ServerProcess, python_path, segb_server
from bench.soak import Posting, caught_up, post_visits

WARM_UP_SECONDS = 5.0
CLIENTS = 4


@dataclass(frozen=True)
class Run:
    version: str  # "this tree" or the commit
    posts_per_second: float
    api_cpu_ms: float  # the API process's CPU a post
    children_cpu_ms: float  # its children's (the views' process)
    clients_cpu_ms: float  # this process's (the posting threads)


def run_once(version: str, package_root: Path | None, robot: OneRobot, keep_views: bool, seconds: float) -> Run:
    """One server of `version` (its package under `package_root`; None: this tree) posted to for `seconds`."""
    env = {"KEEP_VIEWS": "true" if keep_views else "false", "LOGGING_LEVEL": "WARNING"}
    with tempfile.TemporaryDirectory(prefix="segb-versions-") as data:
        with _package_first(package_root):
            server = segb_server("oxigraph", Path(data), env)
        return _posted(version, server, robot, seconds)


def _posted(version: str, server: ServerProcess, robot: OneRobot, seconds: float) -> Run:
    with server:
        with Client(server.url) as client:
            client.publish(robot.first)
        if caught_up(server.url, timeout=600) is None:
            raise RuntimeError(f"{version}: the views were not built within 10 minutes")
        posting, stop = Posting(), threading.Event()
        posters = [
            threading.Thread(target=post_visits, args=(server.url, robot, posting, stop, False), daemon=True)
            for _ in range(CLIENTS)
        ]
        for thread in posters:
            thread.start()
        try:
            time.sleep(WARM_UP_SECONDS)
            assert server.pid is not None
            children = _children(server.pid)
            before = _readings(server.pid, children, posting)
            time.sleep(seconds)
            after = _readings(server.pid, children, posting)
        finally:
            stop.set()
            for thread in posters:
                thread.join()
    posts = max(1, after[0] - before[0])
    return Run(
        version,
        posts / (after[1] - before[1]),
        1000 * (after[2] - before[2]) / posts,
        1000 * (after[3] - before[3]) / posts,
        1000 * (after[4] - before[4]) / posts,
    )


def _readings(pid: int, children: list[int], posting: Posting) -> tuple[int, float, float, float, float]:
    """Posts acknowledged, the clock, and the CPU seconds of the server, its children and this process."""
    own = os.times()
    children_cpu = sum(cpu_seconds(child) for child in children if Path(f"/proc/{child}").exists())
    return posting.acknowledged, time.monotonic(), cpu_seconds(pid), children_cpu, own.user + own.system


def _children(pid: int) -> list[int]:
    found = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True, check=False)
    return [int(child) for child in found.stdout.split()]


@contextlib.contextmanager
def _package_first(package_root: Path | None) -> Iterator[None]:
    """While a server is made: its interpreter finds the package under `package_root` first (the server copies
    the environment when made)."""
    if package_root is None:
        yield
        return
    former = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(part for part in (str(package_root), former) if part)
    try:
        yield
    finally:
        if former is None:
            del os.environ["PYTHONPATH"]
        else:
            os.environ["PYTHONPATH"] = former


@contextlib.contextmanager
def exported(commit: str) -> Iterator[tuple[str, Path]]:
    """The commit's short hash, and a temporary folder whose `segb_server` holds the commit's files (`git
    archive`: nothing is written into the repository)."""
    short = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", commit], capture_output=True, text=True, check=True
    ).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="segb-versions-tree-") as folder:
        tree = Path(folder) / "segb_server"
        tree.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", short], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
        where = imported_from(Path(folder))
        if not where.startswith(str(tree)):  # else the run would compare this tree with itself
            raise RuntimeError(f"the server of {short} would import the package from {where}, not {tree}")
        yield short, Path(folder)


def imported_from(package_root: Path) -> str:
    """Where a server made with `package_root` first imports the package from."""
    with _package_first(package_root):
        env = {**os.environ, "PYTHONPATH": python_path()}  # as the server gets it
    found = subprocess.run(
        [sys.executable, "-c", "import segb_server.backend as b; print(b.__file__)"],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return found.stdout.strip()


def markdown(runs: list[Run], against: str, command: str) -> str:
    mine = [run for run in runs if run.version == "this tree"]
    theirs = [run for run in runs if run.version == against]

    def rates(selected: list[Run]) -> str:
        values = [run.posts_per_second for run in selected]
        return f"{', '.join(f'{value:.0f}' for value in values)} (median {statistics.median(values):.0f})"

    def cpu(selected: list[Run], field: str) -> str:
        return f"{statistics.median(getattr(run, field) for run in selected):.2f}"

    ratio = statistics.median(r.posts_per_second for r in mine) / statistics.median(r.posts_per_second for r in theirs)
    rows = [
        f"`{command}`: the two versions in turns (A B B A …), {len(mine)} runs each; every run, and medians.",
        "",
        f"| | {against} | this tree |",
        "|---|--:|--:|",
        f"| posts/s | {rates(theirs)} | {rates(mine)} |",
        f"| API process CPU ms / post | {cpu(theirs, 'api_cpu_ms')} | {cpu(mine, 'api_cpu_ms')} |",
        f"| its children's (the views' process) | {cpu(theirs, 'children_cpu_ms')} | {cpu(mine, 'children_cpu_ms')} |",
        f"| the clients' | {cpu(theirs, 'clients_cpu_ms')} | {cpu(mine, 'clients_cpu_ms')} |",
        f"| posts/s, this tree ÷ {against} (medians) | | {ratio:.2f} |",
    ]
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.versions", description=__doc__.split("\n\n")[0])
    parser.add_argument("--against", required=True, help="the earlier commit (anything git rev-parse takes)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds: each runs both versions twice (A B B A)")
    parser.add_argument("--seconds", type=float, default=35.0, help="seconds each run is timed")
    parser.add_argument("--views", choices=("on", "off"), default="on", help="every view kept, or none")
    args = parser.parse_args(argv)
    robot = one_robot()
    runs: list[Run] = []
    with exported(args.against) as (short, package_root):
        for _ in range(args.rounds):
            for version in (short, "this tree", "this tree", short):
                root = package_root if version == short else None
                runs.append(run_once(version, root, robot, args.views == "on", args.seconds))
                print(f"  {version}: {runs[-1].posts_per_second:.0f} posts/s", file=sys.stderr, flush=True)
    command = f"python -m bench.versions --against {args.against} --rounds {args.rounds} --seconds {args.seconds:g}"
    print(markdown(runs, short, command + f" --views {args.views}"))
    print("\nmachine: " + "; ".join(f"{k} {v}" for k, v in machine().items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
