"""The server's Prometheus metrics: what is counted as it happens, and the text a scrape reads.

Counters and histograms are recorded where things happen (a post answered, an erasure applied, a bundle served).
With several API workers (`segb serve --workers N`) each worker records into files of its own in
PROMETHEUS_MULTIPROC_DIR (a temporary directory `segb serve` makes and removes), and a scrape, whichever worker
answers it, sums them all (prometheus-client's multiprocess mode). What is read at scrape time (lag, findings,
the store's health) is the same from any worker and is read by the one answering (`readings.py`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from prometheus_client import CollectorRegistry, Counter, Histogram, generate_latest, values
from prometheus_client.metrics_core import Metric
from prometheus_client.multiprocess import MultiProcessCollector
from prometheus_client.registry import Collector

CONTENT_TYPE = "text/plain; version=0.0.4; charset=utf-8"
PREFIX = "segb"

# Recorded here, read by the exposition below (in multiprocess mode through the workers' files instead).
RECORDED = CollectorRegistry(auto_describe=True)

POSTS = Counter(
    f"{PREFIX}_posts",
    "Posts to /ttl answered, by outcome (accepted, refused) and reason (the error code of a refusal).",
    ["outcome", "reason"],
    registry=RECORDED,
)
TRIPLES = Counter(
    f"{PREFIX}_triples",
    "Triples of accepted posts: new (recorded), known (already held), withheld (erased before, not recorded).",
    ["outcome"],
    registry=RECORDED,
)
INGEST_SECONDS = Histogram(
    f"{PREFIX}_ingest_seconds",
    "Time from a post's arrival to its answer, by outcome.",
    ["outcome"],
    buckets=(0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30),
    registry=RECORDED,
)
ERASURES = Counter(
    f"{PREFIX}_erasures", "Erasures applied to the store (a person's, or retention's).", registry=RECORDED
)
EVIDENCE_BUNDLES = Counter(f"{PREFIX}_evidence_bundles_served", "Evidence bundles served.", registry=RECORDED)
WEBHOOK_DELIVERIES = Counter(
    f"{PREFIX}_webhook_deliveries",
    "Webhook deliveries by outcome: delivered, failed (every retry refused), dropped (the queue was full).",
    ["outcome"],
    registry=RECORDED,
)
TRACES_DROPPED = Counter(
    f"{PREFIX}_traces_dropped",
    "Interactions not traced because the export queue was full (OTEL_EXPORTER_OTLP_ENDPOINT slow or away).",
    registry=RECORDED,
)


def record_post(status: int, reason: str | None, seconds: float, triples: dict[str, int]) -> None:
    """One answered post: its status, its refusal's error code, its time, and (accepted) its triples by outcome."""
    outcome = "accepted" if status < 400 else "refused"
    POSTS.labels(outcome, reason or ("" if outcome == "accepted" else f"http_{status}")).inc()
    INGEST_SECONDS.labels(outcome).observe(seconds)
    for kind, count in triples.items():
        if count:
            TRIPLES.labels(kind).inc(count)


def multiprocess() -> bool:
    """Whether this process records into PROMETHEUS_MULTIPROC_DIR (prometheus-client decides it at import)."""
    return values.ValueClass is not values.MutexValue


class _Recorded(Collector):
    def collect(self) -> Iterator[Metric]:
        yield from RECORDED.collect()


def exposition(readings: Iterable[Collector]) -> bytes:
    """The text a scrape reads: what every process recorded, and `readings` taken now."""
    registry = CollectorRegistry(auto_describe=False)
    if multiprocess():
        MultiProcessCollector(registry)
    else:
        registry.register(_Recorded())
    for reading in readings:
        registry.register(reading)
    return generate_latest(registry)
