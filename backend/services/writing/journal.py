"""The journal: every accepted post and clearing, in order, hash-chained, each post with its new triples exactly
as received. It is the source of truth; the triple store is a projection of it (writing/applier.py).

A post's entry keeps only the triples the journal did not hold yet (since the last clearing), so a robot's
cumulative re-publish costs a membership test per triple and adds nothing. Triples are compared as received:
their N-Triples text, original lexical forms and datatypes included. The content is stored as an N-Triples
document compressed with zlib; the receipt covers its SHA-256.

An erasure (erasure.py) removes lines from posts' content and records what it did as an entry of its own; the
chain stays whole, since receipts cover digests of their lines, not the lines themselves (redaction.py).

What the journal reads (receipts, entries, posts, verification) is in journal_reads.py.

Kept in the state database (backend/state): SQLite in DATA_DIR by default (its file: journal_file.py), PostgreSQL
when STATE_URL names one. All work is blocking: async callers use a worker thread.
"""

from __future__ import annotations

import hashlib
import threading
import time
import zlib
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace

from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.errors import ServiceError
from segb_server.backend.services.writing.erasure import (
    Erasure,
    ErasureDone,
    candidates,
    erasure_receipt,
    forget_digests,
    naming_erased,
    redact,
    resource_digest,
)
from segb_server.backend.services.writing.journal_reads import COLUMNS, JournalReads, pending_document
from segb_server.backend.services.writing.journal_reads import JournalEntry as JournalEntry  # re-exported
from segb_server.backend.services.writing.known_digests import KnownDigests
from segb_server.backend.services.writing.receipts import (
    FIELD_NAMES,
    Receipt,
)
from segb_server.backend.services.writing.redaction import RedactionRecord, content_digest
from segb_server.backend.state.database import Database
from segb_server.backend.state.epochs import refuse_older_epoch

EMPTY_SHA256 = hashlib.sha256(b"").hexdigest()
_ROWS_PER_INSERT = 400  # digests per INSERT statement (SQLite allows 32,766 parameters)
RECORDED_KEPT = 20_000  # this process's latest entries whose recording time is kept in memory (`age_of`)
FREE_BYTES_NEEDED = 1 << 20  # below this much free space, readiness reports the journal as not writable

SCHEMA = """
CREATE TABLE IF NOT EXISTS receipts (
    sequence          BIGINT  PRIMARY KEY,
    log_id            TEXT    NOT NULL,
    action            TEXT    NOT NULL,
    "user"            TEXT    NOT NULL,
    claimed_user      TEXT,
    recorded_at       TEXT    NOT NULL,
    payload_sha256    TEXT    NOT NULL,
    triples_received  INTEGER NOT NULL,
    triples_new       INTEGER NOT NULL,
    triples_removed   INTEGER NOT NULL,
    previous_hash     TEXT    NOT NULL,
    receipt_hash      TEXT    NOT NULL
);
CREATE INDEX IF NOT EXISTS receipts_by_log_id ON receipts (log_id);
CREATE TABLE IF NOT EXISTS journal_triples (digest {blob} PRIMARY KEY) {without_rowid};
CREATE TABLE IF NOT EXISTS journal_state (name TEXT PRIMARY KEY, value BIGINT NOT NULL);
CREATE TABLE IF NOT EXISTS erased_triples (digest {blob} PRIMARY KEY) {without_rowid};
CREATE TABLE IF NOT EXISTS erasure_pending (sequence BIGINT PRIMARY KEY, content {blob} NOT NULL);
"""
# Columns the journal added to the ledger's receipts table; added to an older file on opening (re-runnable).
# `redacted_by` (the newest erasure that removed lines of the post) and `redacted_digests` (those lines'
# digests) are the journal's own notes, outside the receipt's hash: the erasure's record is what covers them.
ADDED_COLUMNS = {
    "content_sha256": "TEXT",
    "content": "{blob}",
    "content_digest": "TEXT",
    "triples_withheld": "INTEGER",
    "redacted_by": "BIGINT",
    "redacted_digests": "{blob}",
    "replacements": "{blob}",  # lines an erasure put in place of removed ones (a text with a name redacted)
}


class StorageFull(ServiceError):
    """The journal cannot grow: the disk is full or JOURNAL_MAX_BYTES is reached. Nothing of the post was kept."""

    code = "storage_full"


@dataclass(frozen=True)
class PostEntry:
    """A parsed post on its way into the journal: its receipt fields, and every triple as an N-Triples line
    (as received) with its digest."""

    log_id: str
    user: str
    claimed_user: str | None
    payload_sha256: str
    lines: list[str]
    digests: list[bytes]
    # Triples the post received besides `lines`: re-sent ones the journal held at `epoch`, recognised before
    # parsing (ingest/republish.py). Counted as received, recorded nowhere.
    held: int = 0
    epoch: int | None = None  # the journal's epoch `held` was known at: a post arriving at another one fails


class EpochMoved(Exception):
    """A clearing or an erasure came between a post's reading and its recording: what it counted as held may not
    be (nothing of it was recorded)."""


def triple_digest(line: str) -> bytes:
    """128-bit digest of a triple's N-Triples text: at a billion triples a false match is ~1e-21 likely."""
    return hashlib.blake2b(line.encode("utf-8"), digest_size=16).digest()


def ntriples_document(lines: Sequence[str]) -> bytes:
    return "".join(f"{line} .\n" for line in lines).encode("utf-8")


class Journal(JournalReads):
    """One connection serves every call, under a lock, so appends are serialised and extend one chain; the
    database's write transactions also keep other processes (API workers, other hosts) from forking it."""

    def __init__(self, database: Database, *, max_bytes: int = 0) -> None:
        self.database = database
        self.max_bytes = max_bytes
        self._lock = threading.Lock()
        self._reads = database.reader()
        self._reads_lock = threading.Lock()
        # This process's posts pass it on their way in; an erasure may hold them at it (`posts_held`).
        self._admission = threading.Lock()
        # Digests known to be in the journal since the last clearing, for this epoch: re-published triples
        # then cost no database lookup. Only ever holds digests that were committed; bounded (known_digests.py).
        self._known = KnownDigests()
        self._known_epoch = -1
        self.storage_problem: str | None = None  # why the last write failed for want of space, until one works
        # When this process recorded its latest entries (sequence → epoch seconds): how long the oldest entry the
        # views miss has waited is asked every few posts (posts wait for the views), and is then told from
        # memory, not read under the journal's lock, which the posts' own writes hold
        self._recorded: dict[int, float] = {}
        self._any_erased: bool | None = None  # whether erased_triples holds any digest (None: not read yet)
        with self._lock:
            database.script(SCHEMA)
            with database.writing():
                present = database.columns("receipts")
                for column, kind in ADDED_COLUMNS.items():
                    if column not in present:
                        database.execute(f"ALTER TABLE receipts ADD COLUMN {column} {database.render(kind)}")

    # --- writing ---------------------------------------------------------------------------------------

    def append_posts(self, posts: Sequence[PostEntry]) -> list[Receipt | BaseException]:
        """Record posts in one transaction, chained in order; each keeps only the triples new to the journal.
        A post that fails alone (its own error) fails alone; a failed commit fails them all, keeping nothing."""
        with self._admission, self._lock:
            with self._storage_errors(), self._transaction() as connection:
                epoch = self._epoch(connection)
                if epoch != self._known_epoch:  # a clearing or an erasure (in any process) since the last post
                    self._known, self._known_epoch, self._any_erased = KnownDigests(), epoch, None
                sequence, previous = self._head(connection)
                outcomes: list[Receipt | BaseException] = []
                held_back: list[set[bytes]] = []
                for post in posts:
                    connection.execute("SAVEPOINT post")
                    try:
                        if post.epoch is not None and post.epoch != epoch:
                            raise EpochMoved()
                        receipt, content, withheld = self._post_receipt(connection, post, sequence + 1, previous)
                        self._insert(connection, receipt, content)
                    except Exception as error:
                        connection.execute("ROLLBACK TO post")
                        outcomes.append(error)
                        continue
                    finally:
                        connection.execute("RELEASE post")
                    sequence, previous = receipt.sequence, receipt.receipt_hash
                    outcomes.append(receipt)
                    held_back.append(withheld)
                self._check_size()
            self._remember_recorded(outcome.sequence for outcome in outcomes if isinstance(outcome, Receipt))
            # Committed: only now may the cache say these triples are in the journal (those held back are not:
            # the next post re-sending them is told again).
            for post, outcome in zip(posts, outcomes, strict=True):
                if isinstance(outcome, Receipt):
                    self._known.update(digest for digest in post.digests if digest not in held_back[0])
                    held_back.pop(0)
        return outcomes

    def append_clear(self, *, log_id: str, user: str, claimed_user: str | None) -> Receipt:
        """Record a clearing of the events graph: the journal forgets every triple it held (they may come again),
        and the receipt counts them as removed."""
        with self._lock, self._storage_errors():
            receipt, epoch = self._clear(log_id, user, claimed_user)
            self._known, self._known_epoch = KnownDigests(), epoch
            self._remember_recorded([receipt.sequence])
        return receipt

    def epoch(self) -> int:
        """The journal's epoch: a new one with every clearing and erasure, in any process."""
        with self._reads_lock:
            return self._epoch(self._reads)

    def holds(self, digests: Iterable[bytes]) -> bool:
        """Whether the journal is known to hold each of these triples (from memory: False may mean forgotten)."""
        known = self._known
        return all(digest in known for digest in digests)

    def _remember_recorded(self, sequences: Iterable[int]) -> None:
        """Under the lock, once committed: these entries were recorded now (the oldest forgotten past a bound)."""
        now = time.time()
        for sequence in sequences:
            self._recorded[sequence] = now
        while len(self._recorded) > RECORDED_KEPT:
            del self._recorded[next(iter(self._recorded))]  # the oldest: a dict keeps its insertion order

    @contextmanager
    def posts_held(self) -> Iterator[None]:
        """This process's posts wait to be recorded while the block runs (an erasure finding what to erase and
        recording it with nothing recorded between); other processes' posts are not held."""
        with self._admission:
            yield

    def append_erasure(self, erasure: Erasure) -> ErasureDone | None:
        """Remove the lines `erasure` selects from every post's content and record it as one entry, in one
        transaction; returns its receipt and the lines removed (None, and nothing recorded, when no post holds
        such a line). The entry keeps the removed lines only until the store has dropped them
        (`erasure_applied`)."""
        found, scanned_through = candidates(self.database, self._lock, erasure.selection)
        with self._lock, self._storage_errors():
            with self._transaction() as connection:
                sequence, previous = self._head(connection)
                redaction = redact(connection, erasure, found, scanned_through, sequence + 1)
                if not redaction.items:
                    return None
                digests = [triple_digest(line[:-2].decode()) for line in redaction.removed]
                if erasure.withhold:
                    digests += [resource_digest(iri) for iri in sorted(erasure.resources)]
                forget_digests(connection, digests, erasure.withhold)
                self._next_epoch(connection)  # every process's cache of held triples starts again
                record = RedactionRecord(erasure.kind, erasure.reason, redaction.items)
                receipt = _chained(erasure_receipt(erasure, record, sequence + 1, previous))
                self._insert(connection, receipt, record.document())
                connection.execute(
                    "INSERT INTO erasure_pending (sequence, content) VALUES (?, ?)",
                    (receipt.sequence, zlib.compress(pending_document(redaction.removed, redaction.added))),
                )
            # The removed triples may come again (or, withheld, be told of again): the cache forgets them all.
            self._known, self._known_epoch = KnownDigests(), -1
            self._any_erased = self._any_erased or erasure.withhold
        return ErasureDone(receipt, len(redaction.items), redaction.removed, redaction.added)

    def erasure_applied(self, through: int, epoch: int | None = None) -> None:
        """The store has applied every erasure through `through`: the lines they removed are kept no longer.
        `epoch`: the applier's apply epoch; StateFenced (nothing changed) when a newer one was drawn since."""
        with self._lock, self._transaction() as connection:
            if epoch is not None:
                refuse_older_epoch(connection, epoch)
            connection.execute("DELETE FROM erasure_pending WHERE sequence <= ?", (through,))

    def _clear(self, log_id: str, user: str, claimed_user: str | None) -> tuple[Receipt, int]:
        with self._transaction() as connection:
            removed = connection.execute("SELECT COUNT(*) FROM journal_triples").fetchone()[0]
            connection.execute("DELETE FROM journal_triples")
            epoch = self._next_epoch(connection)
            sequence, previous = self._head(connection)
            receipt = _chained(
                Receipt(
                    sequence + 1, log_id, "delete_all", user, claimed_user, utc_iso(), EMPTY_SHA256,
                    0, 0, removed, EMPTY_SHA256, previous, "",
                )
            )  # fmt: skip
            self._insert(connection, receipt, b"")
        return receipt, epoch

    def _post_receipt(
        self, connection: Database, post: PostEntry, sequence: int, previous: str
    ) -> tuple[Receipt, bytes, set[bytes]]:
        """The post's receipt and content, and the digests of its triples an erasure removed: those are not
        recorded again (a robot's client re-sends everything it ever logged), and the receipt counts them."""
        unknown = [index for index, digest in enumerate(post.digests) if digest not in self._known]
        new_digests = _insert_new_digests(connection, [post.digests[index] for index in unknown])
        withheld = erased_among(connection, new_digests) if new_digests and self._erasures(connection) else set()
        if new_digests and self._any_erased:
            fresh = {post.digests[i]: post.lines[i] for i in unknown if post.digests[i] in new_digests}
            naming = naming_erased(
                connection, {digest: line for digest, line in fresh.items() if digest not in withheld}
            )
            _forget_new(connection, naming)  # not the journal's: sent again, they are withheld again
            withheld |= naming
        new_lines = [
            post.lines[i] for i in unknown if post.digests[i] in new_digests and post.digests[i] not in withheld
        ]
        content = ntriples_document(new_lines)
        receipt = Receipt(
            sequence, post.log_id, "ingest", post.user, post.claimed_user, utc_iso(), post.payload_sha256,
            len(post.lines) + post.held, len(new_lines), 0, hashlib.sha256(content).hexdigest(), previous, "",
            content_digest(content), len(withheld),
        )  # fmt: skip
        return _chained(receipt), content, withheld

    def _insert(self, connection: Database, receipt: Receipt, content: bytes) -> None:
        connection.execute(
            f"INSERT INTO receipts ({COLUMNS}, content) VALUES ({', '.join(['?'] * (len(FIELD_NAMES) + 1))})",
            (*receipt.row(), zlib.compress(content) if content else b""),
        )

    def compact(self) -> None:
        """Leave nothing an erasure removed in the journal's files: with no read of this process under way, so
        the write-ahead log empties whole."""
        with self._lock, self._reads_lock:
            self.database.compact()

    def close(self) -> None:
        with self._lock, self._reads_lock:
            if self._reads is not self.database:
                self._reads.close()
            self.database.close()

    # --- plumbing --------------------------------------------------------------------------------------

    def _erasures(self, connection: Database) -> bool:
        """Whether any erasure withheld triples from coming back (read once a process; erasures set it)."""
        if self._any_erased is None:
            self._any_erased = connection.execute("SELECT 1 FROM erased_triples LIMIT 1").fetchone() is not None
        return self._any_erased

    def _next_epoch(self, connection: Database) -> int:
        epoch = self._epoch(connection) + 1
        connection.execute(
            "INSERT INTO journal_state (name, value) VALUES ('epoch', ?) "
            "ON CONFLICT (name) DO UPDATE SET value = excluded.value",
            (epoch,),
        )
        return epoch

    def _epoch(self, connection: Database) -> int:
        row = connection.execute("SELECT value FROM journal_state WHERE name = 'epoch'").fetchone()
        return row[0] if row else 0

    def _check_size(self) -> None:
        if self.max_bytes and self.database.size_bytes() > self.max_bytes:
            raise StorageFull(
                f"The journal would grow past {self.max_bytes} bytes (JOURNAL_MAX_BYTES); posts are refused until "
                "the limit is raised or space is freed."
            )

    @contextmanager
    def _transaction(self) -> Iterator[Database]:
        with self.database.writing():
            yield self.database

    def ping(self) -> None:
        """Raise StateUnavailable unless the journal's database answers."""
        with self._lock:
            self.database.ping()

    def storage_ok(self) -> bool:
        """Whether the journal can take writes: True unless the last write failed for want of space and there is
        still none (so readiness recovers as soon as space returns, before the next post). A database whose
        free space this server cannot see is taken to have room until a write says otherwise."""
        if self.storage_problem is None:
            return True
        free = self.database.free_bytes()
        over_quota = bool(self.max_bytes) and self.database.size_bytes() > self.max_bytes
        return (free is None or free > FREE_BYTES_NEEDED) and not over_quota

    @contextmanager
    def _storage_errors(self) -> Iterator[None]:
        try:
            yield
        except StorageFull as full:
            self.storage_problem = full.message
            raise
        except Exception as error:
            if not self.database.out_of_space(error):
                raise
            self.storage_problem = f"the disk holding {self.database.where} is full ({error})"
            raise StorageFull(
                f"The journal cannot grow: {self.storage_problem}. Posts are refused until space is freed; "
                "nothing of this post was kept."
            ) from None
        self.storage_problem = None


def _chained(receipt: Receipt) -> Receipt:
    return replace(receipt, receipt_hash=receipt.computed_hash())


def erased_among(connection: Database, digests: set[bytes]) -> set[bytes]:
    """Those of `digests` an erasure withheld: taken out of the journal's triples again, and returned."""
    found: set[bytes] = set()
    ordered = list(digests)
    for start in range(0, len(ordered), _ROWS_PER_INSERT):
        chunk = ordered[start : start + _ROWS_PER_INSERT]
        marks = ", ".join(["?"] * len(chunk))
        found.update(
            row[0] for row in connection.execute(f"SELECT digest FROM erased_triples WHERE digest IN ({marks})", chunk)
        )
    withheld = list(found)
    for start in range(0, len(withheld), _ROWS_PER_INSERT):
        chunk = withheld[start : start + _ROWS_PER_INSERT]
        connection.execute(f"DELETE FROM journal_triples WHERE digest IN ({', '.join(['?'] * len(chunk))})", chunk)
    return found


def _forget_new(connection: Database, digests: set[bytes]) -> None:
    ordered = list(digests)
    for start in range(0, len(ordered), _ROWS_PER_INSERT):
        chunk = ordered[start : start + _ROWS_PER_INSERT]
        connection.execute(f"DELETE FROM journal_triples WHERE digest IN ({', '.join(['?'] * len(chunk))})", chunk)


def _insert_new_digests(connection: Database, digests: list[bytes]) -> set[bytes]:
    """Insert the digests; return those that were not there yet (the database decides, atomically)."""
    new: set[bytes] = set()
    for start in range(0, len(digests), _ROWS_PER_INSERT):
        chunk = digests[start : start + _ROWS_PER_INSERT]
        rows = connection.execute(
            f"INSERT INTO journal_triples (digest) VALUES {', '.join(['(?)'] * len(chunk))} "
            "ON CONFLICT (digest) DO NOTHING RETURNING digest",
            chunk,
        ).fetchall()
        new.update(row[0] for row in rows)
    return new
