"""The journal's side of an erasure: which lines of which posts go, and the one transaction that removes them
and appends the erasure's entry.

The lines are found twice: first in a scan that does not hold posts up (batches, each read under the journal's
lock for a moment), then, inside the write transaction, again in the posts the scan found and in every post
recorded since, so a post arriving meanwhile cannot slip through. What to select may itself have been found in the
store as of an entry (a person's resources, by a rule): a later post touching them may hold more to select (a new
message of theirs, whose text links to nothing erased), so the transaction then records nothing and says so
(`SelectionOutdated`), for the selection to be found again. Either the whole erasure is committed — the
posts' content redacted, the triples' digests moved out of the journal's set (into the withheld ones, for a
person), the erasure's entry and the lines the store must drop — or none of it.
"""

from __future__ import annotations

import hashlib
import zlib
from collections.abc import Callable, Iterable, Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any

from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.redaction import Redacted, RedactionRecord, line_digest, lines_of
from segb_server.backend.state.database import Database

SCAN_BATCH = 500
_ROWS_PER_STATEMENT = 400


def _nothing(_line: bytes) -> bytes | None:
    return None


@dataclass(frozen=True)
class LineSelection:
    """Which content lines an erasure removes: of the posts `posts(recorded_at)` admits, the lines `lines` picks
    (a line as the content holds it: `<s> <p> o .`); `replace` gives the line put in place of one it removes (a
    text with a name redacted), None for none."""

    posts: Callable[[str], bool]
    lines: Callable[[bytes], bool]
    replace: Callable[[bytes], bytes | None] = _nothing

    def either(self, other: LineSelection) -> LineSelection:
        """The lines this selection or `other` picks (of the posts this one admits), each replaced by the first
        selection that picks it."""
        return LineSelection(
            self.posts,
            lambda line: self.lines(line) or other.lines(line),
            lambda line: self.replace(line) if self.lines(line) else other.replace(line),
        )


def touching(resources: Iterable[str]) -> LineSelection:
    """Every line whose subject or object is one of `resources` (IRIs), in every post."""
    wanted = {f"<{iri}>".encode() for iri in resources}

    def line_touches(line: bytes) -> bool:
        subject, _, rest = line.partition(b" ")
        if subject in wanted:
            return True
        _predicate, _, obj = rest.partition(b" ")
        return obj[:-2] in wanted  # the object, without the line's closing " ."

    return LineSelection(lambda _recorded_at: True, line_touches)


def recorded_before(cutoff: str) -> LineSelection:
    """Every line of the posts recorded before `cutoff` (ISO 8601 UTC, as receipts write it)."""
    return LineSelection(lambda recorded_at: recorded_at < cutoff, lambda _line: True)


@dataclass(frozen=True)
class Erasure:
    """An erasure as asked: who, why, what kind, which lines, and whether re-sent triples are held back.
    `found_as_of`: the journal entry through which the selection was found (None: it depends on no entry)."""

    log_id: str
    user: str
    kind: str
    reason: str
    selection: LineSelection
    withhold: bool
    found_as_of: int | None = None
    # The IRIs erased (a person's resources): withheld too, a triple naming one is recorded by no later post.
    resources: frozenset[str] = frozenset()


class SelectionOutdated(Exception):
    """A post recorded after the entry an erasure's selection was found at holds lines it selects: that post may
    hold more to erase than the selection knows (nothing was recorded)."""

    def __init__(self, sequence: int) -> None:
        super().__init__(f"post {sequence} touches what the erasure selects and was recorded after it was found")
        self.sequence = sequence


def candidates(
    database: Database, lock: AbstractContextManager[object], selection: LineSelection
) -> tuple[list[int], int]:
    """The posts holding at least one line to erase, and the last entry scanned (read in batches, each under
    `lock` only while it is read: decompressing and matching, seconds at a million triples, holds no post up)."""
    found: list[int] = []
    position = 0
    while True:
        with lock:
            rows = database.execute(
                "SELECT sequence, recorded_at, content, replacements FROM receipts WHERE sequence > ? "
                f"AND action = 'ingest' ORDER BY sequence LIMIT {SCAN_BATCH}",
                (position,),
            ).fetchall()
            if not rows:
                head = database.execute("SELECT MAX(sequence) FROM receipts").fetchone()[0] or 0
                return found, max(position, head)
        for sequence, recorded_at, blob, replaced in rows:  # outside the lock
            if selection.posts(recorded_at) and any(
                map(selection.lines, lines_of(_inflate(blob) + _inflate(replaced)))
            ):
                found.append(sequence)
        position = rows[-1][0]


@dataclass(frozen=True)
class ErasureDone:
    """An erasure recorded: its receipt, the posts it redacted, the lines it removed (to find elsewhere) and the
    lines it put in place of some of them."""

    receipt: Receipt
    posts: int
    removed: list[bytes]
    added: list[bytes] = field(default_factory=list)


@dataclass(frozen=True)
class Redaction:
    """What the transaction removed: the record's items, the removed lines and the lines put in their place
    (for the store)."""

    items: list[Redacted]
    removed: list[bytes]
    added: list[bytes] = field(default_factory=list)


def redact(
    connection: Database, erasure: Erasure, found: list[int], scanned_through: int, record_sequence: int
) -> Redaction:
    """Inside the write transaction: remove the selected lines from the posts found and from every post since
    the scan, noting their digests beside each post, and keep the lines put in place of some of them beside the
    post too (`replacements`: not received, so outside what its receipt covers; the erasure's record covers
    them); SelectionOutdated (the transaction is then rolled back) when one of them was recorded after the
    selection was found."""
    items: list[Redacted] = []
    removed: list[bytes] = []
    added: list[bytes] = []
    selected = erasure.selection.lines
    for sequence, log_id, recorded_at, blob, redacted, replaced in _posts(connection, found, scanned_through):
        if not erasure.selection.posts(recorded_at):
            continue
        lines, replacements = lines_of(_inflate(blob)), lines_of(_inflate(replaced))
        gone = [line for line in lines if selected(line)]
        gone_replacements = [line for line in replacements if selected(line)]  # an earlier redaction's, redacted
        if not gone and not gone_replacements:
            continue
        if erasure.found_as_of is not None and sequence > erasure.found_as_of:
            raise SelectionOutdated(sequence)
        kept_lines = [line for line in lines if not selected(line)]
        staying = [line for line in replacements if not selected(line)]
        swaps = [(line, new) for line in gone + gone_replacements if (new := erasure.selection.replace(line))]
        fresh = list(dict.fromkeys(new for _, new in swaps if new not in staying and new not in kept_lines))
        kept = b"".join(line + b"\n" for line in kept_lines)
        now_replacing = b"".join(line + b"\n" for line in staying + fresh)
        digests = (redacted or b"") + b"".join(line_digest(line) for line in gone)
        connection.execute(
            "UPDATE receipts SET content = ?, redacted_digests = ?, redacted_by = ?, replacements = ? "
            "WHERE sequence = ?",
            (_deflate(kept), digests, record_sequence, _deflate(now_replacing), sequence),
        )
        items.append(
            Redacted(
                sequence, log_id, len(gone), hashlib.sha256(kept).hexdigest(),
                hashlib.sha256(now_replacing).hexdigest() if now_replacing else None,
                [(line_digest(old).hex(), line_digest(new).hex()) for old, new in swaps],
            )
        )  # fmt: skip
        removed += gone + gone_replacements
        added += fresh
    return Redaction(items, removed, added)


def _posts(connection: Database, found: list[int], scanned_through: int) -> Iterator[Any]:
    columns = (
        "SELECT sequence, log_id, recorded_at, content, redacted_digests, replacements FROM receipts "
        "WHERE action = 'ingest'"
    )
    for start in range(0, len(found), _ROWS_PER_STATEMENT):
        chunk = found[start : start + _ROWS_PER_STATEMENT]
        yield from connection.execute(f"{columns} AND sequence IN ({', '.join(['?'] * len(chunk))})", chunk)
    yield from connection.execute(f"{columns} AND sequence > ? ORDER BY sequence", (scanned_through,))


def _inflate(blob: bytes | None) -> bytes:
    return zlib.decompress(blob) if blob else b""


def _deflate(document: bytes) -> bytes:
    return zlib.compress(document) if document else b""


def forget_digests(connection: Database, digests: list[bytes], withhold: bool) -> None:
    """The removed triples are no longer the journal's (they may be recorded again); a person's are withheld:
    recorded again by no later post."""
    for start in range(0, len(digests), _ROWS_PER_STATEMENT):
        chunk = digests[start : start + _ROWS_PER_STATEMENT]
        connection.execute(f"DELETE FROM journal_triples WHERE digest IN ({', '.join(['?'] * len(chunk))})", chunk)
        if withhold:
            connection.execute(
                f"INSERT INTO erased_triples (digest) VALUES {', '.join(['(?)'] * len(chunk))} "
                "ON CONFLICT (digest) DO NOTHING",
                chunk,
            )


def resource_digest(iri: str) -> bytes:
    """An erased IRI as `erased_triples` keeps it, beside the triples' digests (no triple's text starts the
    same): a digest, so the journal's files do not name the person."""
    return hashlib.blake2b(f"erased resource <{iri}>".encode(), digest_size=16).digest()


def naming_erased(connection: Database, lines: dict[bytes, str]) -> set[bytes]:
    """Of `lines` (digest → `<s> <p> o` text), those whose subject or object is an IRI an erasure withheld: a
    robot re-attaching new data to what was erased (a new emotion in an erased annotation) records none of it."""
    named: dict[bytes, set[bytes]] = {}
    for digest, line in lines.items():
        subject, _predicate, obj = line.split(" ", 2)
        for term in (subject, obj):
            if term.startswith("<") and not term.startswith("<<"):
                named.setdefault(resource_digest(term[1:-1]), set()).add(digest)
    ordered = list(named)
    found: set[bytes] = set()
    for start in range(0, len(ordered), _ROWS_PER_STATEMENT):
        chunk = ordered[start : start + _ROWS_PER_STATEMENT]
        marks = ", ".join(["?"] * len(chunk))
        for (erased,) in connection.execute(f"SELECT digest FROM erased_triples WHERE digest IN ({marks})", chunk):
            found |= named[bytes(erased)]
    return found


def erasure_receipt(erasure: Erasure, record: RedactionRecord, sequence: int, previous: str) -> Receipt:
    document = record.document()
    digest = hashlib.sha256(document).hexdigest()
    return Receipt(
        sequence, erasure.log_id, "erase", erasure.user, None, utc_iso(), digest, 0, 0, record.triples_removed,
        digest, previous, "",
    )  # fmt: skip
