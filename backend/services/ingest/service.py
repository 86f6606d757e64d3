"""Storing robots' RDF: parse, skolemise, write only what the store does not have yet."""

from __future__ import annotations

import logging
import time
import uuid
from dataclasses import dataclass

from pyoxigraph import Quad

from segb_server.backend.services.ingest.group_commit import GroupCommit
from segb_server.backend.services.ingest.parsing import parse_triples
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.services.ops.ledger import Entry, Ledger
from segb_server.backend.services.ops.result_cache import DataVersion
from segb_server.backend.store.base import Store

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
        self._writer: GroupCommit[_Post, IngestResult] = GroupCommit(self._commit)

    def ingest(self, payload: RdfPayload, *, actor: str) -> IngestResult:
        """Parse (concurrently with other posts), then write and record the post; returns once its triples
        and its ledger receipt are committed."""
        started = time.perf_counter()
        quads = parse_triples(
            payload.data, payload.rdf_format, max_triples=self._max_triples, skolem_base=self._skolem_base
        )
        return self._writer.submit(_Post(payload, actor, quads, started))

    def _commit(self, posts: list[_Post]) -> list[IngestResult | BaseException]:
        """Write a batch of parsed posts one after another, then record all their receipts in one ledger
        transaction: under concurrent load that is one commit for many posts instead of one each."""
        outcomes: list[IngestResult | BaseException] = []
        for post in posts:
            try:
                new = self._store.insert_new(post.quads) if post.quads else 0
            except Exception as error:  # this post fails (e.g. the store is down); the others are still written
                outcomes.append(error)
                continue
            duration_ms = round((time.perf_counter() - post.started) * 1000, 3)
            outcomes.append(IngestResult(str(uuid.uuid4()), len(post.quads), new, duration_ms))
        accepted = [
            (post, result) for post, result in zip(posts, outcomes, strict=True) if isinstance(result, IngestResult)
        ]
        if any(result.triples_new for _, result in accepted):
            self._version.bump()
        if self._ledger is not None and accepted:
            self._ledger.append_many([_entry(post, result) for post, result in accepted])
        for post, result in accepted:
            logger.debug(
                "ingest log_id=%s actor=%s claimed_user=%s bytes=%d received=%d new=%d ms=%.1f",
                result.log_id,
                post.actor,
                post.payload.claimed_user,
                len(post.payload.data),
                result.triples_received,
                result.triples_new,
                result.duration_ms,
            )
        return outcomes

    def delete_all(self, *, actor: str, claimed_user: str | None = None) -> ClearResult:
        # Outside any ingest batch, so the ledger orders the clearing exactly where the store saw it.
        with self._writer.exclusive():
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


@dataclass(frozen=True)
class _Post:
    """A parsed post waiting to be written."""

    payload: RdfPayload
    actor: str
    quads: list[Quad]
    started: float


def _entry(post: _Post, result: IngestResult) -> Entry:
    return Entry("ingest", result.log_id, post.actor, post.payload.claimed_user, post.payload.data,
                 result.triples_received, result.triples_new)  # fmt: skip
