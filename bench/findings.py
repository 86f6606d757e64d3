"""The audit rules at size: findings upkeep per post, a new post's finding on GET /findings after its 201, and
/findings pages, on the embedded store holding 100k or 1M triples while a robot publishes 10 posts a second.

    python -m bench.findings                         # 100,000 and 1,000,000 triples (about 15 minutes)
    python -m bench.findings --sizes 100000 --posts 300

Upkeep is timed in-process on the loaded store (each findings view's `update` for one post's new triples: the
work the views' keeper does after the 201); the rest over loopback HTTP against `segb serve --only api`.
Prints a Markdown section for docs/performance.md.
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
from pyoxigraph import Quad, RdfFormat, parse

from bench.__main__ import LIVE_RATE, count_lines, segb_import, write_dataset
from bench.client import Client
from bench.measure import Latency
from bench.server import segb_server
from segb_server.backend.config import Settings
from segb_server.backend.services.container import build_services
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.store.factory import open_store
from tests.support.robot_posts import LivePost, live_posts, robot_of

UPKEEP_POSTS = 60  # posts whose findings upkeep is timed in-process
PAGE_REPEATS = 30
GIVE_UP_SECONDS = 5.0
UNANSWERED = "unanswered-message"
HEADER = (
    "| triples | findings built (s) | upkeep per post p50 / p95 (ms) | finding shown after the 201 p50 / p99 (ms) "
    "| resolved p50 / p99 (ms) | /findings p50 / p95 (ms) | filtered by robot | violations only | page 10 (cursor) "
    "| /rules |"
)


@dataclass
class Freshness:
    """Seconds from a post's 201 until GET /findings shows (or stops showing) what it changed."""

    appeared: list[float] = field(default_factory=list)  # a heard message's "never answered" finding
    resolved: list[float] = field(default_factory=list)  # that finding gone after the reply's post
    missed: int = 0
    posts: int = 0
    errors: int = 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.findings", description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--posts", type=int, default=600, help="posts of the live robot (at 10 a second)")
    args = parser.parse_args(argv)
    root = Path(tempfile.mkdtemp(prefix="segb-bench-findings-"))
    print(HEADER)
    print("|---|---|---|---|---|---|---|---|---|---|")
    for size in args.sizes:
        print(_row(root, size, args.posts), flush=True)
    return 0


def _row(root: Path, size: int, post_count: int) -> str:
    data_dir = root / f"findings-{size}"
    files = write_dataset(root, size)
    segb_import("oxigraph", data_dir, files)
    posts = live_posts(post_count, "findings")
    with segb_server("oxigraph", data_dir) as server:
        built = _wait_built(server.url)
        freshness = Freshness()
        pages: dict[str, list[float]] = {}
        stop = threading.Event()
        poster = threading.Thread(target=_publish, args=(server.url, posts, stop, freshness), daemon=True)
        poster.start()
        try:
            pages = _pages(server.url, robot_of(posts[0].payload))
            poster.join()  # the robot goes on until its posts run out: every one of them is timed
        finally:
            stop.set()
            poster.join()
    upkeep = _upkeep(data_dir, live_posts(UPKEEP_POSTS, "upkeep"))
    shown, resolved = Latency.of(freshness.appeared), Latency.of(freshness.resolved)
    page = {name: Latency.of(samples) for name, samples in pages.items()}
    return (
        f"| {count_lines(files):,} | {built:.1f} | {upkeep.p50:.1f} / {upkeep.p95:.1f} | {shown.p50:.0f} / "
        f"{shown.p99:.0f} ({len(freshness.appeared)} posts, {freshness.missed} missed) | {resolved.p50:.0f} / "
        f"{resolved.p99:.0f} | {page['first'].p50:.1f} / {page['first'].p95:.1f} | {page['robot'].p50:.1f} / "
        f"{page['robot'].p95:.1f} | {page['violations'].p50:.1f} / {page['violations'].p95:.1f} | "
        f"{page['deep'].p50:.1f} / {page['deep'].p95:.1f} | {page['rules'].p50:.1f} / {page['rules'].p95:.1f} |"
    )


def _wait_built(url: str, timeout: float = 3600) -> float:
    """Seconds until every rule's findings are served from its kept rows."""
    begin = time.monotonic()
    while time.monotonic() - begin < timeout:
        answer = httpx.get(f"{url}/findings", params={"limit": 1}, timeout=600)
        if answer.status_code == 200 and set(answer.json()["served_from"].values()) == {"rows"}:
            ready = httpx.get(f"{url}/healthz/ready", timeout=60).json()
            if "reports_lag" not in ready:
                return time.monotonic() - begin
        time.sleep(0.5)
    raise RuntimeError("the findings were not built in time")


def _publish(url: str, posts: list[LivePost], stop: threading.Event, into: Freshness) -> None:
    """The robot posts at LIVE_RATE; after a post that adds a heard message (then its reply's post), a reader
    polls the robot's unanswered messages until the finding appears (then goes). Polling runs in this thread
    between posts, so a slow finding delays the next post rather than being timed late."""
    robot = robot_of(posts[0].payload)
    waiting: str | None = None
    with Client(url) as client, httpx.Client(base_url=url, timeout=60) as reader:
        started = time.perf_counter()
        for index, post in enumerate(posts):
            if stop.wait(max(0.0, started + index / LIVE_RATE - time.perf_counter())):
                return
            try:
                client.publish(post.payload)
            except OSError:
                into.errors += 1
                continue
            answered = time.perf_counter()
            into.posts += 1
            heard = [message for message in post.messages if "message_user_" in message]  # what the human said
            if heard and waiting is None:
                if _until(reader, robot, heard[0], present=True, since=answered, into=into.appeared):
                    waiting = heard[0]
                else:
                    into.missed += 1
            elif waiting is not None and post.messages:
                _until(reader, robot, waiting, present=False, since=answered, into=into.resolved)
                waiting = None


def _until(reader: httpx.Client, robot: str, message: str, *, present: bool, since: float, into: list[float]) -> bool:
    while time.perf_counter() - since < GIVE_UP_SECONDS:
        found = reader.get("/findings", params={"rule": UNANSWERED, "robot": robot, "limit": 1000}).json()
        if any(f["focus"] == message for f in found["findings"]) == present:
            into.append(time.perf_counter() - since)
            return True
        time.sleep(0.01)
    return False


def _pages(url: str, robot: str) -> dict[str, list[float]]:
    samples: dict[str, list[float]] = {"first": [], "robot": [], "violations": [], "deep": [], "rules": []}
    with httpx.Client(base_url=url, timeout=120) as client:
        for _ in range(PAGE_REPEATS):
            samples["first"].append(_timed(client, "/findings", {"limit": 100}))
            samples["robot"].append(_timed(client, "/findings", {"limit": 100, "robot": robot}))
            samples["violations"].append(_timed(client, "/findings", {"limit": 100, "severity": "violation"}))
            samples["rules"].append(_timed(client, "/rules", {}))
            after = None
            for _ in range(9):
                body = client.get("/findings", params={"limit": 100, **({"after": after} if after else {})}).json()
                after = body["next"]
                if not after:
                    break
            if after:
                samples["deep"].append(_timed(client, "/findings", {"limit": 100, "after": after}))
    if not samples["deep"]:
        samples["deep"] = [0.0]
    return samples


def _timed(client: httpx.Client, path: str, params: dict[str, object]) -> float:
    begin = time.perf_counter()
    answer = client.get(path, params=params)
    elapsed = time.perf_counter() - begin
    answer.raise_for_status()
    return elapsed


def _upkeep(data_dir: Path, posts: list[LivePost]) -> Latency:
    """Each findings view's update for one post's new triples, on the store as the server left it."""
    settings = Settings(store="oxigraph", data_dir=data_dir)
    store = open_store(settings)
    services = build_services(settings, store)
    try:
        findings = services.findings
        assert findings.kept is not None and findings.shapes is not None
        views = [*findings.kept.views(), findings.shapes]
        for view in views:
            through = view.stored_through()
            assert through is not None, f"{view.name} is not built"
            view.ready = True
        seconds = []
        for sequence, post in enumerate(posts, start=10**9):
            quads = [Quad(q.subject, q.predicate, q.object) for q in parse(post.payload.encode(), RdfFormat.TURTLE)]
            store.apply(quads, sequence)
            delta = Delta.of(quads)
            begin = time.perf_counter()
            for view in views:
                view.update(delta, sequence)
            seconds.append(time.perf_counter() - begin)
        return Latency.of(seconds)
    finally:
        services.close()
        store.close()


if __name__ == "__main__":
    raise SystemExit(main())
