"""Apply lag at a steady rate: one robot posting at a fixed rate, and how long after each 201 its triples can be
read.

Each post carries one triple of its own (`<urn:bench:visible:N> <urn:bench:posted> "N"`). A second thread
reads that resource (`/resource`, a query the server runs on the store in-process: when the applier has
written the triple), a third asks for the triple through `/sparql` (`ASK`) until the answer is true: what a
reader of the SPARQL endpoint sees, including that endpoint's own cost (on the embedded store, a query over a
fresh snapshot once the data changed).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import httpx

from bench.client import BenchError, Client
from bench.measure import Latency

POLL_SECONDS = 0.005
GIVE_UP_SECONDS = 30.0


@dataclass(frozen=True)
class SteadyLag:
    """One robot at a fixed rate: its posts' latency and the time from each 201 to visibility."""

    posts: int
    rate: float  # posts per second reached
    post_latency: Latency
    applied: Latency | None  # 201 to the triple read from the store (`/resource`); None when none was
    visible: Latency | None  # 201 to the first true answer of the ASK through /sparql
    not_visible: int  # posts still invisible after GIVE_UP_SECONDS
    errors: int


def marked(payload: str, index: int) -> tuple[str, str]:
    """The payload with a triple unique to it, and that triple's subject."""
    subject = f"urn:bench:visible:{index}"
    return f'{payload}\n<{subject}> <urn:bench:posted> "{index}" .\n', subject


@dataclass
class Checker:
    """Times each post's triple until a reader finds it, in a thread of its own. When it falls behind (a check
    outlasting the interval between posts) it skips to the newest post rather than time one late, so no figure
    includes time spent queued in the bench."""

    url: str
    path: str
    params: Callable[[str], dict[str, str]]
    found: Callable[[dict[str, Any]], bool]
    delays: list[float] = field(default_factory=list)
    missing: int = 0
    skipped: int = 0

    def __post_init__(self) -> None:
        self.pending: queue.Queue[tuple[str, float] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def finish(self) -> None:
        self.pending.put(None)
        self._thread.join()

    def _run(self) -> None:
        headers = {"Accept": "application/sparql-results+json"}
        with httpx.Client(base_url=self.url, timeout=30, headers=headers) as client:
            while (item := self.pending.get()) is not None:
                if not self.pending.empty():
                    self.skipped += 1
                    continue
                subject, answered = item
                seen = self._poll(client, subject, answered)
                if seen is None:
                    self.missing += 1
                else:
                    self.delays.append(seen - answered)

    def _poll(self, client: httpx.Client, subject: str, since: float) -> float | None:
        while time.perf_counter() - since < GIVE_UP_SECONDS:
            answer = client.get(self.path, params=self.params(subject))
            if answer.status_code == 200 and self.found(answer.json()):
                return time.perf_counter()
            time.sleep(POLL_SECONDS)
        return None


def in_store(url: str) -> Checker:
    """`/resource` of the post's own subject: a query the server runs on the store in-process."""
    return Checker(url, "/resource", lambda subject: {"iri": subject}, lambda body: bool(body.get("outgoing")))


def through_sparql(url: str) -> Checker:
    """`ASK` through the SPARQL endpoint, as any SPARQL client would read."""
    return Checker(
        url,
        "/sparql",
        lambda subject: {"query": f"ASK {{ <{subject}> ?p ?o }}"},
        lambda body: body.get("boolean") is True,
    )


def steady_lag(url: str, payloads: list[str], rate: float, seconds: float) -> SteadyLag:
    """Post `rate` payloads a second for `seconds`, each checked for visibility by two readers."""
    count = min(len(payloads), max(1, round(rate * seconds)))
    checkers = [in_store(url), through_sparql(url)]
    latencies, errors, elapsed = _post_at_rate(url, payloads[:count], rate, checkers)
    for checker in checkers:
        checker.finish()
    applied, visible = checkers
    return SteadyLag(
        posts=count,
        rate=count / elapsed,
        post_latency=Latency.of(latencies),
        applied=Latency.of(applied.delays) if applied.delays else None,
        visible=Latency.of(visible.delays) if visible.delays else None,
        not_visible=applied.missing + visible.missing,
        errors=errors,
    )


def _post_at_rate(
    url: str, payloads: list[str], rate: float, checkers: list[Checker]
) -> tuple[list[float], int, float]:
    latencies: list[float] = []
    errors = 0
    with Client(url) as client:
        started = time.perf_counter()
        for index, payload in enumerate(payloads):
            delay = started + index / rate - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            body, subject = marked(payload, index)
            begin = time.perf_counter()
            try:
                client.publish(body)
            except (BenchError, OSError):
                errors += 1
                continue
            answered = time.perf_counter()
            latencies.append(answered - begin)
            for checker in checkers:
                checker.pending.put((subject, answered))
        elapsed = time.perf_counter() - started
    return latencies, errors, elapsed
