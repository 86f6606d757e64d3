"""Storing robots' RDF: parse, skolemise, write only what the store does not have yet."""

from __future__ import annotations

import logging
import time
import uuid
from dataclasses import dataclass

from backend.services.payloads import RdfPayload
from backend.services.rdf_parsing import parse_triples
from backend.services.result_cache import DataVersion
from backend.store.base import Store

logger = logging.getLogger("segb.ingest")


@dataclass(frozen=True)
class IngestResult:
    """What one accepted post did."""

    log_id: str
    triples_received: int
    triples_new: int
    duration_ms: float


class IngestService:
    """Idempotent ingest: the client re-sends its whole graph every time, so the work that grows with the
    store (finding what is new) is a per-triple membership test, and only new triples are written."""

    def __init__(self, store: Store, *, skolem_base: str, max_triples: int, version: DataVersion | None = None) -> None:
        self._store = store
        self._skolem_base = skolem_base
        self._max_triples = max_triples
        self._version = version or DataVersion()

    def ingest(self, payload: RdfPayload, *, actor: str) -> IngestResult:
        started = time.perf_counter()
        quads = parse_triples(
            payload.data, payload.rdf_format, max_triples=self._max_triples, skolem_base=self._skolem_base
        )
        new = self._store.insert_new(quads) if quads else 0
        if new:
            self._version.bump()
        result = IngestResult(
            log_id=str(uuid.uuid4()),
            triples_received=len(quads),
            triples_new=new,
            duration_ms=round((time.perf_counter() - started) * 1000, 3),
        )
        logger.info(
            "ingest log_id=%s actor=%s claimed_user=%s bytes=%d received=%d new=%d ms=%.1f",
            result.log_id,
            actor,
            payload.claimed_user,
            len(payload.data),
            result.triples_received,
            result.triples_new,
            result.duration_ms,
        )
        return result

    def delete_all(self, *, actor: str) -> int:
        removed = self._store.clear()
        self._version.bump()
        logger.warning("delete_all actor=%s removed=%d", actor, removed)
        return removed
