"""Where the time of one small post goes inside the server: each ingest step timed in-process, no HTTP."""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

from bench.measure import Latency
from segb_server.backend.config import Settings
from segb_server.backend.services.container import build_services
from segb_server.backend.services.ingest.parsing import parse_quads, skolemized
from segb_server.backend.services.ingest.payloads import decode_ingest_body
from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.writing.applier import Applier
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.store.factory import open_store

STEPS = (
    "JSON body decoding",
    "Turtle parsing and skolemising (pyoxigraph)",
    "journal entry: N-Triples lines and digests",
    "journal append (SQLite)",
    "applier: entry read back and written to the store (RocksDB)",
)
# Not on the post's path: the reports' thread does it after the 201, beside the next requests.
MAINTENANCE = "after the 201: the reports' rows brought up to the post (their own thread)"
SKOLEM_BASE = "http://amor-segb/.well-known/genid/"
EDGE_POSTS = 30


def breakdown(payloads: list[str], folder: Path) -> dict[str, Latency]:
    """The steps `POST /ttl` runs (backend/services/ingest/service.py, then the applier), on a fresh on-disk
    journal and store built as the server builds them, one post at a time as INGEST_ACK=store does on the
    embedded store; then how long the reports' thread takes to bring the reports up to that post."""
    settings = Settings(store="oxigraph", data_dir=folder)
    store = open_store(settings)
    services = build_services(settings, store)
    upkeep = _reports_upkeep(services)
    if upkeep is not None:
        upkeep.start()
    steps = (*STEPS, MAINTENANCE) if upkeep is not None else STEPS
    seconds: dict[str, list[float]] = {step: [] for step in steps}
    try:
        for payload in payloads:
            marks = _one_post(payload, services.writes.journal, services.writes.applier)
            if upkeep is not None:
                upkeep.wait_until_current(600)
                marks.append(time.perf_counter())
            for step, begin, end in zip(steps, marks, marks[1:], strict=False):
                seconds[step].append(end - begin)
    finally:
        services.close()
        store.close()
    figures = {step: Latency.of(values) for step, values in seconds.items()}
    upkeep = seconds.get(MAINTENANCE, [])
    if len(upkeep) >= 2 * EDGE_POSTS:
        # Whether the upkeep of one post grows with what the store already holds.
        figures[f"{MAINTENANCE}, first {EDGE_POSTS} posts"] = Latency.of(upkeep[:EDGE_POSTS])
        figures[f"{MAINTENANCE}, last {EDGE_POSTS} posts"] = Latency.of(upkeep[-EDGE_POSTS:])
    return figures


def _reports_upkeep(services: Any) -> Any:
    """What keeps the reports current (its thread started, `wait_until_current` returns once it has caught
    up), wherever the services hold it; None when they hold nothing of the kind."""
    reports = getattr(services, "reports", None)
    candidates = (
        getattr(getattr(services, "writes", None), "keeper", None),
        getattr(services, "views", None),
        getattr(services, "projector", None),
        getattr(reports, "maintainer", None),
    )
    for candidate in candidates:
        if candidate is not None and hasattr(candidate, "wait_until_current") and hasattr(candidate, "start"):
            return candidate
    return None


def _one_post(payload: str, journal: Journal, applier: Applier) -> list[float]:
    body = json.dumps({"ttl_content": payload, "user": "bench"}).encode()
    marks = [time.perf_counter()]
    decoded = decode_ingest_body(
        body, content_type="application/json", content_encoding=None, claimed_user=None,
        max_decompressed_bytes=1 << 28,
    )  # fmt: skip
    marks.append(time.perf_counter())
    quads = skolemized(decoded.data, parse_quads(decoded.data, decoded.rdf_format, max_triples=2_000_000), SKOLEM_BASE)
    marks.append(time.perf_counter())
    entry = post_entry(quads, "bench", None, hashlib.sha256(decoded.data).hexdigest())
    marks.append(time.perf_counter())
    (receipt,) = journal.append_posts([entry])
    if isinstance(receipt, BaseException):
        raise receipt
    marks.append(time.perf_counter())
    applier.apply_pending()  # as the posting thread does with INGEST_ACK=store
    marks.append(time.perf_counter())
    return marks
