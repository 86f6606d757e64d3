"""Where the time of one small post goes inside the server: each ingest step timed in-process, no HTTP."""

from __future__ import annotations

import json
import time
from pathlib import Path

from bench.measure import Latency
from segb_server.backend.services.ingest.parsing import parse_triples
from segb_server.backend.services.ingest.payloads import decode_ingest_body
from segb_server.backend.services.ops.ledger import Ledger
from segb_server.backend.store.oxigraph import OxigraphStore

STEPS = ("JSON body decoding", "Turtle parsing (pyoxigraph)", "store write (RocksDB)", "ledger receipt (SQLite)")


def breakdown(payloads: list[str], folder: Path) -> dict[str, Latency]:
    """The same steps `POST /ttl` runs (backend/services/ingest.py), on a fresh on-disk store and ledger."""
    store = OxigraphStore("http://amor-segb/events", folder / "oxigraph")
    ledger = Ledger(folder / "ledger.sqlite3")
    seconds: dict[str, list[float]] = {step: [] for step in STEPS}
    try:
        for payload in payloads:
            body = json.dumps({"ttl_content": payload, "user": "bench"}).encode()
            marks = [time.perf_counter()]
            decoded = decode_ingest_body(
                body, content_type="application/json", content_encoding=None, claimed_user=None,
                max_decompressed_bytes=1 << 28,
            )  # fmt: skip
            marks.append(time.perf_counter())
            quads = parse_triples(
                decoded.data, decoded.rdf_format, max_triples=2_000_000, skolem_base="http://x/.well-known/genid/"
            )
            marks.append(time.perf_counter())
            new = store.insert_new(quads)
            marks.append(time.perf_counter())
            ledger.append(
                action="ingest", log_id="bench", user="bench", claimed_user=None, payload=decoded.data,
                triples_received=len(quads), triples_new=new,
            )  # fmt: skip
            marks.append(time.perf_counter())
            for step, begin, end in zip(STEPS, marks, marks[1:], strict=False):
                seconds[step].append(end - begin)
    finally:
        ledger.close()
        store.close()
    return {step: Latency.of(values) for step, values in seconds.items()}
