"""The benchmark workloads, each driving a running server over HTTP and returning measured figures."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import httpx
from pyoxigraph import RdfFormat, parse
from tqdm import tqdm

from bench.client import BenchError, Client
from bench.measure import Latency
from bench.probes import LagFigures, ReadinessProbe, wait_caught_up
from bench.workloads import CumulativePost
from segb_server.backend.services.writing.journal_file import JOURNAL_FILE

REPORTS_FILE = "reports.sqlite3"  # where the server keeps the reports' rows, beside the journal


def triple_count(payload: str) -> int:
    return sum(1 for _ in parse(payload.encode(), RdfFormat.TURTLE))


@dataclass
class SmallPosts:
    latency: Latency
    posts_per_second: float
    triples_per_post: float


def small_posts(url: str, payloads: list[str], label: str) -> SmallPosts:
    """Sequential posts of one event's delta each, from one client with a kept-alive connection."""
    seconds = []
    with Client(url) as client:
        started = time.perf_counter()
        for payload in tqdm(payloads, desc=f"small posts · {label}", leave=False):
            begin = time.perf_counter()
            client.publish(payload)
            seconds.append(time.perf_counter() - begin)
        elapsed = time.perf_counter() - started
    triples = sum(map(triple_count, payloads)) / len(payloads)
    return SmallPosts(Latency.of(seconds), len(payloads) / elapsed, triples)


@dataclass
class ManyRobots:
    latency: Latency
    posts_per_second: float
    triples_per_second: float
    errors: int
    triples_sent: int
    triples_stored: int
    lag: LagFigures | None = None  # a SEGB server's readiness during the run, and its catching up after it


def many_robots(
    url: str, robots: list[list[str]], label: str, count_stored: Callable[[], int], *, readiness: bool = False
) -> ManyRobots:
    """Every robot posts its own events concurrently (one thread and connection each); afterwards
    `count_stored` tells how many triples the store holds (it started empty). With `readiness`,
    `/healthz/ready` is sampled during the run and polled after it until the store and the reports caught up,
    and only then are the triples counted."""
    probe = ReadinessProbe(url) if readiness else None
    with probe or nullcontext():
        seconds, errors, elapsed = _post_concurrently(url, robots, label)
    lag = LagFigures.of(probe.samples, wait_caught_up(url)) if probe else None
    distinct: set[object] = set()
    for payloads in robots:
        for payload in payloads:
            distinct.update(parse(payload.encode(), RdfFormat.TURTLE))
    posts = sum(map(len, robots))
    return ManyRobots(
        Latency.of(seconds), posts / elapsed, len(distinct) / elapsed, errors, len(distinct), count_stored(), lag
    )


def _post_concurrently(url: str, robots: list[list[str]], label: str) -> tuple[list[float], int, float]:
    seconds: list[float] = []
    errors = 0
    lock = threading.Lock()
    progress = tqdm(total=sum(map(len, robots)), desc=f"{len(robots)} robots · {label}", leave=False)

    def run(payloads: list[str]) -> None:
        nonlocal errors
        with Client(url) as client:
            for payload in payloads:
                begin = time.perf_counter()
                try:
                    client.publish(payload)
                except (BenchError, OSError):
                    with lock:
                        errors += 1
                with lock:
                    seconds.append(time.perf_counter() - begin)
                    progress.update()

    started = time.perf_counter()
    with ThreadPoolExecutor(len(robots)) as pool:
        list(pool.map(run, robots))
    elapsed = time.perf_counter() - started
    progress.close()
    return seconds, errors, elapsed


def stored_triples(url: str) -> int:
    """Triples a SEGB server holds, counted through its own `/sparql`.

    Not from its export: on the embedded store, GET /events can abort the server process when another request
    is in flight while it streams (pyoxigraph's quad iterator is pulled from more than one thread), so the
    export is only read once nothing else runs."""
    answer = httpx.get(
        f"{url}/sparql",
        params={"query": "SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }"},
        headers={"Accept": "application/sparql-results+json"},
        timeout=600,
    )
    answer.raise_for_status()
    return int(answer.json()["results"]["bindings"][0]["n"]["value"])


def export_size(url: str) -> tuple[int, int]:
    """Triples and bytes of a SEGB server's graph as N-Triples (its own export, GET /events)."""
    triples = size = 0
    with httpx.stream("GET", f"{url}/events", headers={"Accept": "application/n-triples"}, timeout=600) as response:
        response.raise_for_status()
        for line in response.iter_lines():
            if line.strip():
                triples += 1
                size += len(line.encode()) + 1
    return triples, size


@dataclass(frozen=True)
class JournalSize:
    """The journal on disk after a run, against the graph it holds as N-Triples."""

    database_bytes: int  # DATA_DIR/journal.sqlite3
    wal_bytes: int  # DATA_DIR/journal.sqlite3-wal (not yet checkpointed into the database)
    graph_triples: int
    graph_ntriples_bytes: int
    payload_bytes: int  # everything the robot sent, summed over its posts
    reports_bytes: int = 0  # DATA_DIR/reports.sqlite3 and its -wal: the reports' rows, beside the journal


def journal_size(data_dir: Path, url: str, payload_bytes: int) -> JournalSize:
    database = data_dir / JOURNAL_FILE
    wal = database.with_name(database.name + "-wal")
    triples, size = export_size(url)
    return JournalSize(
        database.stat().st_size,
        _size(wal),
        triples,
        size,
        payload_bytes,
        _size(data_dir / REPORTS_FILE) + _size(data_dir / f"{REPORTS_FILE}-wal"),
    )


def _size(path: Path) -> int:
    return path.stat().st_size if path.exists() else 0


@dataclass
class CumulativePoint:
    interactions: int
    payload_triples: int
    payload_bytes: int
    new_triples: int
    seconds: float


@dataclass
class Cumulative:
    points: list[CumulativePoint] = field(default_factory=list)
    journal: JournalSize | None = None  # measured after the last post

    @property
    def payload_bytes(self) -> int:
        return sum(point.payload_bytes for point in self.points)

    @property
    def last(self) -> CumulativePoint:
        return self.points[-1]


def cumulative(url: str, posts: list[CumulativePost] | object, label: str, total: int) -> Cumulative:
    """One robot re-publishing its whole graph after every interaction."""
    result = Cumulative()
    with Client(url) as client:
        for post in tqdm(posts, total=total, desc=f"cumulative · {label}", leave=False):  # type: ignore[call-overload]
            begin = time.perf_counter()
            answer = client.publish(post.payload)
            elapsed = time.perf_counter() - begin
            result.points.append(
                CumulativePoint(
                    post.interactions,
                    answer["triples_received"],
                    len(post.payload.encode()),
                    answer["triples_new"],
                    elapsed,
                )
            )
    return result
