"""The benchmark workloads, each driving a running server over HTTP and returning measured figures."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import httpx
from pyoxigraph import RdfFormat, parse
from tqdm import tqdm

from bench.client import BenchError, Client
from bench.measure import Latency
from bench.workloads import CumulativePost


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


def many_robots(url: str, robots: list[list[str]], label: str, count_stored: Callable[[], int]) -> ManyRobots:
    """Every robot posts its own events concurrently (one thread and connection each); afterwards
    `count_stored` tells how many triples the store holds (it started empty)."""
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
    distinct: set[object] = set()
    for payloads in robots:
        for payload in payloads:
            distinct.update(parse(payload.encode(), RdfFormat.TURTLE))
    posts = sum(map(len, robots))
    return ManyRobots(
        Latency.of(seconds), posts / elapsed, len(distinct) / elapsed, errors, len(distinct), count_stored()
    )


def exported_triples(url: str) -> int:
    """Triples a SEGB server holds, counted from its own export (GET /events as N-Triples)."""
    with httpx.stream("GET", f"{url}/events", headers={"Accept": "application/n-triples"}, timeout=600) as response:
        response.raise_for_status()
        return sum(1 for line in response.iter_lines() if line.strip())


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


def probe_health(url: str, stop: threading.Event, interval: float = 0.02) -> list[float]:
    """`/healthz/ready` latencies, polled until `stop` is set (run in a thread beside a load)."""
    seconds = []
    with httpx.Client(base_url=url) as client:
        while not stop.is_set():
            begin = time.perf_counter()
            client.get("/healthz/ready", timeout=10)
            seconds.append(time.perf_counter() - begin)
            time.sleep(interval)
    return seconds


ReportFigures = tuple[Latency, int, Latency]


def report_queries(url: str, repeats: int, label: str) -> dict[str, ReportFigures | str]:
    """Every report of `GET /reports`: latency of repeated requests (served from the result cache where the
    store has one), latency of the first request after a write, and the row count; or, for a report the
    server refused (say, a query timeout at 1M triples), what it answered."""
    with httpx.Client(base_url=url, timeout=600) as client:
        listing = client.get("/reports")
        if listing.status_code != 200:
            return {}
        names = [report["name"] for report in listing.json()["reports"]]
        figures: dict[str, ReportFigures | str] = {}
        for name in tqdm(names, desc=f"reports · {label}", leave=False):
            try:
                figures[name] = _one_report(client, name, repeats)
            except httpx.HTTPStatusError as error:
                detail = " ".join(error.response.text[:120].replace("|", "/").split())  # fits a table cell
                figures[name] = f"HTTP {error.response.status_code}: {detail}"
    return figures


def _one_report(client: httpx.Client, name: str, repeats: int) -> ReportFigures:
    client.get(f"/reports/{name}").raise_for_status()  # warm caches once
    seconds, rows = [], 0
    for _ in range(repeats):
        begin = time.perf_counter()
        answer = client.get(f"/reports/{name}")
        seconds.append(time.perf_counter() - begin)
        answer.raise_for_status()
        rows = len(answer.json()["rows"])
    after_write = []
    for tick in range(max(3, repeats // 4)):
        # One new, unrelated triple: the store changed, so nothing cached may answer.
        triple = f'<urn:bench:tick> <urn:bench:{name}> "{tick}" .\n'
        client.post("/ttl", content=triple, headers={"Content-Type": "application/n-triples"}).raise_for_status()
        begin = time.perf_counter()
        client.get(f"/reports/{name}").raise_for_status()
        after_write.append(time.perf_counter() - begin)
    return Latency.of(seconds), rows, Latency.of(after_write)
