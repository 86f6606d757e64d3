"""Storing robots' RDF: parse, skolemise, write only what the store does not have yet."""

from __future__ import annotations

import logging
import time
import uuid
from dataclasses import dataclass

from backend.services.ledger import Ledger
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


@dataclass(frozen=True)
class ClearResult:
    """What one clearing of the events graph did."""

    log_id: str
    triples_removed: int


class IngestService:
    """Idempotent ingest: the client re-sends its whole graph every time, so the work that grows with the
    store (finding what is new) is a per-triple membership test, and only new triples are written.

    With a ledger, every accepted post and every clearing leaves a receipt there, whoever calls (the API,
    the demo loader), so no write path can skip it."""

    def __init__(
        self,
        store: Store,
        *,
        skolem_base: str,
        max_triples: int,
        version: DataVersion | None = None,
        ledger: Ledger | None = None,
    ) -> None:
        self._store = store
        self._ledger = ledger
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
        if self._ledger is not None:
            self._ledger.append(
                action="ingest",
                log_id=result.log_id,
                user=actor,
                claimed_user=payload.claimed_user,
                payload=payload.data,
                triples_received=result.triples_received,
                triples_new=result.triples_new,
            )
        return result

    def delete_all(self, *, actor: str, claimed_user: str | None = None) -> ClearResult:
        removed = self._store.clear()
        self._version.bump()
        result = ClearResult(log_id=str(uuid.uuid4()), triples_removed=removed)
        logger.warning("delete_all log_id=%s actor=%s removed=%d", result.log_id, actor, removed)
        if self._ledger is not None:
            self._ledger.append(
                action="delete_all",
                log_id=result.log_id,
                user=actor,
                claimed_user=claimed_user,
                payload=b"",  # no RDF is received: the receipt carries the SHA-256 of the empty payload
                triples_removed=removed,
            )
        return result
