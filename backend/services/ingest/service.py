"""Storing robots' RDF, journal first: parse, check, record in the journal, then (when asked) wait for the store.

Every write goes through here — a post, a clearing, a file import, the demo — so every write has its receipt
in the journal before the store sees any of it, and the store only ever holds what the journal holds.
"""

from __future__ import annotations

import hashlib
import logging
import time
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import IO, Literal, cast

from pyoxigraph import NamedNode, Quad, RdfFormat, parse

from segb_server.backend.auth import PermissionDenied
from segb_server.backend.services.errors import OUTAGES, InvalidParameter, ServiceError
from segb_server.backend.services.ingest.group_commit import GroupCommit
from segb_server.backend.services.ingest.parsing import invalid_rdf, parse_quads, refuse_triple_terms, skolemized
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.services.ingest.republish import BlockMemory
from segb_server.backend.services.ingest.skolem import might_contain_blank_nodes
from segb_server.backend.services.writing.journal import EpochMoved, PostEntry, triple_digest
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.write_path import WritePath
from segb_server.backend.store.base import StoreUnavailable
from segb_server.backend.store.terms import term_text
from segb_server.backend.vocabulary import CREDITING

logger = logging.getLogger("segb.ingest")

Ack = Literal["journal", "store"]
IMPORT_BATCH_TRIPLES = 20_000
FILE_FORMATS = {
    ".ttl": RdfFormat.TURTLE,
    ".turtle": RdfFormat.TURTLE,
    ".nt": RdfFormat.N_TRIPLES,
    ".ntriples": RdfFormat.N_TRIPLES,
}
UNREADABLE_FILE = "segb import reads Turtle (.ttl, .turtle) or N-Triples (.nt, .ntriples) files"
Progress = Callable[[int], None]
# A payload's SHA-256 is worked out on a thread of its own while the payload is read (hashlib lets go of the
# GIL), so a large re-publish's answer does not wait for both in turn: about 3.5 ms of a 7 MB post.
DIGEST_BESIDE_BYTES = 1 << 20
_DIGESTS = ThreadPoolExecutor(max_workers=2, thread_name_prefix="payload-digest")


class JournalBacklogFull(ServiceError):
    """The store is behind by more entries than JOURNAL_MAX_BACKLOG: posts wait until it catches up (503)."""

    code = "journal_backlog_full"


class NotYetApplied(StoreUnavailable):
    """A post is in the journal, but the store did not apply it within INGEST_APPLY_TIMEOUT_SECONDS."""


@dataclass(frozen=True)
class IngestResult:
    """What one accepted post did."""

    log_id: str
    triples_received: int
    triples_new: int
    duration_ms: float
    sequence: int
    triples_withheld: int = 0  # triples an erasure removed, sent again and not recorded


@dataclass(frozen=True)
class ClearResult:
    log_id: str
    triples_removed: int
    sequence: int


@dataclass(frozen=True)
class ImportResult:
    path: Path
    triples_read: int
    triples_new: int


class IngestService:
    """Idempotent ingest: the client re-sends its whole graph every time, so the blocks of it an account had
    recorded are skipped before parsing (republish.py), the work that grows with the journal is one membership
    test per triple parsed, and only new triples are recorded and written.

    `ack` decides when a post is answered: once its entry is durable in the journal ("journal"), or once the
    store has applied it too ("store", so the next read shows it)."""

    def __init__(
        self,
        writes: WritePath,
        *,
        skolem_base: str,
        max_triples: int,
        ack: Ack,
        apply_timeout: float,
        max_backlog: int,
    ) -> None:
        self.writes = writes
        self.journal = writes.journal
        self.ack = ack
        self._skolem_base = skolem_base
        self._max_triples = max_triples
        self._apply_timeout = apply_timeout
        self._max_backlog = max_backlog
        self._writer: GroupCommit[PostEntry, Receipt] = GroupCommit(writes.journal.append_posts)
        self.blocks = BlockMemory()  # the re-sent blocks each account had recorded, skipped unparsed

    def ingest(self, payload: RdfPayload, *, actor: str, scopes: tuple[str, ...] = ()) -> IngestResult:
        """Parse (concurrently with other posts), check, then journal the post; returns once its entry is
        durable (and applied, with ack "store")."""
        started = time.perf_counter()
        self._refuse_past_backlog()
        receipt, received, parsed = self._record(payload, actor, scopes)
        self._acknowledge(receipt)
        duration_ms = round((time.perf_counter() - started) * 1000, 3)
        logger.debug(
            "ingest log_id=%s actor=%s claimed_user=%s bytes=%d received=%d parsed=%d new=%d ms=%.1f",
            receipt.log_id, actor, payload.claimed_user, len(payload.data), received, parsed, receipt.triples_new,
            duration_ms,
        )  # fmt: skip
        withheld = receipt.triples_withheld or 0
        if withheld:
            # Said without quoting them: the log must not bring back what was erased.
            logger.warning(
                "post log_id=%s actor=%s re-sent %d erased triples; they were not recorded", receipt.log_id, actor,
                withheld,
            )  # fmt: skip
        return IngestResult(receipt.log_id, received, receipt.triples_new, duration_ms, receipt.sequence, withheld)

    def _record(self, payload: RdfPayload, actor: str, scopes: tuple[str, ...]) -> tuple[Receipt, int, int]:
        """Read the payload for what is new (republish.py), check it and journal it: its receipt, the triples
        received and those parsed. Read whole again when a clearing or an erasure came between reading and recording."""
        account, digest = (actor, scopes), payload_digest(payload.data)
        epoch = self.journal.epoch()
        reading = self.blocks.read(payload.data, payload.rdf_format, account, epoch, self._max_triples)
        check_scopes(reading.quads, scopes)
        quads = skolemized(reading.parsed, reading.quads, self._skolem_base) if reading.parsed else reading.quads
        payload_sha256 = digest.result()
        if reading.overlaps(quads):  # a skipped block's subject is also among those parsed: read whole
            return self._record_whole(payload, actor, scopes, payload_sha256)
        post = post_entry(quads, actor, payload.claimed_user, payload_sha256, held=reading.held, epoch=epoch)
        try:
            receipt = self._writer.submit(post)
        except EpochMoved:
            return self._record_whole(payload, actor, scopes, payload_sha256)
        self.blocks.recorded(reading, account, epoch, receipt.triples_withheld or 0, self.journal.holds)
        return receipt, len(quads) + reading.held_quads, len(quads)

    def _record_whole(
        self, payload: RdfPayload, actor: str, scopes: tuple[str, ...], payload_sha256: str
    ) -> tuple[Receipt, int, int]:
        quads = parse_quads(payload.data, payload.rdf_format, max_triples=self._max_triples)
        check_scopes(quads, scopes)
        post = post_entry(skolemized(payload.data, quads, self._skolem_base), actor, payload.claimed_user,
                          payload_sha256)  # fmt: skip
        return self._writer.submit(post), len(quads), len(quads)

    def delete_all(self, *, actor: str, claimed_user: str | None = None) -> ClearResult:
        receipt = self.journal.append_clear(log_id=str(uuid.uuid4()), user=actor, claimed_user=claimed_user)
        logger.warning("delete_all log_id=%s actor=%s removed=%d", receipt.log_id, actor, receipt.triples_removed)
        self._acknowledge(receipt)
        return ClearResult(receipt.log_id, receipt.triples_removed, receipt.sequence)

    def import_file(self, path: Path, *, actor: str, progress: Progress) -> ImportResult:
        """Journal a Turtle or N-Triples file in batches (an entry each); `progress(n)` hears of every n bytes.

        A file that may hold blank nodes is parsed whole, because skolemisation needs each blank node's full
        surroundings; other files stream, so memory stays at one batch."""
        rdf_format = format_for(path)
        digest = _file_sha256(path)
        read = new = 0
        last: Receipt | None = None
        for quads, consumed in _file_batches(path, rdf_format, self._skolem_base):
            check_scopes(quads, ())
            last = self._writer.submit(post_entry(quads, actor, None, digest))
            read, new = read + len(quads), new + last.triples_new
            progress(consumed)
        if last is not None:
            self._acknowledge(last)
        return ImportResult(path, read, new)

    def _refuse_past_backlog(self) -> None:
        behind = self.writes.backlog()
        if self._max_backlog and behind > self._max_backlog:
            raise JournalBacklogFull(
                f"The store is {behind} entries behind the journal (JOURNAL_MAX_BACKLOG is {self._max_backlog}); "
                "posts are accepted again as it catches up.",
                retry_after=5,
            )

    def _acknowledge(self, receipt: Receipt) -> None:
        if self.ack == "journal":
            self.writes.entries_written()
            return
        try:
            # Not waiting for another thread's step: a post then waits INGEST_APPLY_TIMEOUT_SECONDS at most.
            self.writes.entries_written()
            self.writes.apply_now(wait=False)
        except OUTAGES as error:
            raise NotYetApplied(
                f"kept in the journal as log_id {receipt.log_id}, but it could not be applied yet ({error}); it is "
                "applied as soon as the store answers"
            ) from None
        if not self.writes.wait_applied(receipt.sequence, self._apply_timeout):
            raise NotYetApplied(
                f"kept in the journal as log_id {receipt.log_id}; the store has not applied it within "
                f"{self._apply_timeout:g} s (INGEST_APPLY_TIMEOUT_SECONDS)"
            )


def payload_digest(data: bytes) -> Future[str]:
    """The payload's SHA-256 (hex), on a thread of its own when the payload is large."""
    if len(data) >= DIGEST_BESIDE_BYTES:
        return _DIGESTS.submit(lambda: hashlib.sha256(data).hexdigest())
    done: Future[str] = Future()
    done.set_result(hashlib.sha256(data).hexdigest())
    return done


def post_entry(
    quads: list[Quad],
    user: str,
    claimed_user: str | None,
    payload_sha256: str,
    *,
    held: int = 0,
    epoch: int | None = None,
) -> PostEntry:
    """A post as the journal records it: each distinct triple as its N-Triples line, as received (`held`: the
    triples of re-sent blocks left unparsed, which the journal held at `epoch`)."""
    lines = list(dict.fromkeys(f"{term_text(q.subject)} {q.predicate} {term_text(q.object)}" for q in quads))
    digests = [triple_digest(x) for x in lines]
    return PostEntry(str(uuid.uuid4()), user, claimed_user, payload_sha256, lines, digests, held, epoch)


def check_scopes(quads: list[Quad], scopes: tuple[str, ...]) -> None:
    """With write scopes, every subject named by an IRI must start with one of them (blank nodes are the
    post's own), and so must the agent a statement credits with an act, words or a state (`CREDITING`): a
    robot's token may not put acts in another robot's record. The first that does not refuses the whole post."""
    if not scopes:
        return
    for quad in quads:
        subject, credited = quad.subject, quad.object
        if isinstance(subject, NamedNode) and not subject.value.startswith(scopes):
            raise PermissionDenied(
                f"The token may write about {', '.join(scopes)} only; the post describes <{subject.value}>."
            )
        if (
            quad.predicate.value in CREDITING
            and isinstance(credited, NamedNode)
            and not credited.value.startswith(scopes)
        ):
            raise PermissionDenied(
                f"The token may write about {', '.join(scopes)} only; the post credits <{credited.value}> "
                f"(<{quad.predicate.value}>)."
            )


def format_for(path: Path) -> RdfFormat:
    try:
        return FILE_FORMATS[path.suffix.lower()]
    except KeyError:
        raise InvalidParameter("file", f"{path.name}: {UNREADABLE_FILE}") from None


def _file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as file:
        while chunk := file.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()


def _file_batches(path: Path, rdf_format: RdfFormat, skolem_base: str) -> Iterator[tuple[list[Quad], int]]:
    """The file's triples in batches, each with the bytes consumed to read it."""
    size = path.stat().st_size
    if _might_contain_blank_nodes(path):
        data = path.read_bytes()
        quads = skolemized(data, parse_quads(data, rdf_format, max_triples=len(data)), skolem_base)
        for start in range(0, len(quads), IMPORT_BATCH_TRIPLES):
            end = start + IMPORT_BATCH_TRIPLES
            yield quads[start:end], size if end >= len(quads) else 0
        return
    with path.open("rb") as raw:
        parser = parse(cast(IO[bytes], raw), rdf_format)
        position = 0
        try:
            while batch := list(islice(parser, IMPORT_BATCH_TRIPLES)):
                refuse_triple_terms(batch, rdf_format)
                consumed, position = raw.tell() - position, raw.tell()
                yield batch, consumed
        except SyntaxError as error:
            raise invalid_rdf(error, rdf_format) from None


def _might_contain_blank_nodes(path: Path) -> bool:
    with path.open("rb") as file:
        previous = b""
        while chunk := file.read(1 << 20):
            if might_contain_blank_nodes(previous[-1:] + chunk):
                return True
            previous = chunk
    return False
