"""The journal: every accepted post and clearing, in order, hash-chained, each post with its new triples exactly
as received. It is the source of truth; the triple store is a projection of it (services/ingest/applier.py).

A post's entry keeps only the triples the journal did not hold yet (since the last clearing), so a robot's
cumulative re-publish costs a membership test per triple and adds nothing. Triples are compared as received:
their N-Triples text, original lexical forms and datatypes included. The content is stored as an N-Triples
document compressed with zlib; the receipt covers its SHA-256.

SQLite (a file in DATA_DIR, or memory) in WAL mode. All work is blocking: async callers use a worker thread.
"""

from __future__ import annotations

import hashlib
import shutil
import sqlite3
import threading
import zlib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path

from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.errors import NotFound, ServiceError
from segb_server.backend.services.ingest.receipts import (
    FIELD_NAMES,
    GENESIS_HASH,
    ChainCheck,
    Receipt,
    Verification,
)
from segb_server.backend.services.ops.file_lock import FileLock

JOURNAL_FILE = "ledger.sqlite3"  # the journal grew out of the ingest ledger and keeps its file
EMPTY_SHA256 = hashlib.sha256(b"").hexdigest()
_ROWS_PER_INSERT = 400  # digests per INSERT statement (SQLite allows 32,766 parameters)
FREE_BYTES_NEEDED = 1 << 20  # below this much free space, readiness reports the journal as not writable

SCHEMA = """
CREATE TABLE IF NOT EXISTS receipts (
    sequence          INTEGER PRIMARY KEY,
    log_id            TEXT    NOT NULL,
    action            TEXT    NOT NULL,
    user              TEXT    NOT NULL,
    claimed_user      TEXT,
    recorded_at       TEXT    NOT NULL,
    payload_sha256    TEXT    NOT NULL,
    triples_received  INTEGER NOT NULL,
    triples_new       INTEGER NOT NULL,
    triples_removed   INTEGER NOT NULL,
    previous_hash     TEXT    NOT NULL,
    receipt_hash      TEXT    NOT NULL
);
CREATE TABLE IF NOT EXISTS journal_triples (digest BLOB PRIMARY KEY) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS journal_state (name TEXT PRIMARY KEY, value INTEGER NOT NULL);
"""
# Columns the journal added to the ledger's receipts table; added to an older file on opening (re-runnable).
ADDED_COLUMNS = {"content_sha256": "TEXT", "content": "BLOB"}
COLUMNS = ", ".join(FIELD_NAMES)


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


@dataclass(frozen=True)
class JournalEntry:
    """One entry as the applier reads it: its place, what it did, its content (an N-Triples document)."""

    sequence: int
    action: str
    content: bytes


def triple_digest(line: str) -> bytes:
    """128-bit digest of a triple's N-Triples text: at a billion triples a false match is ~1e-21 likely."""
    return hashlib.blake2b(line.encode("utf-8"), digest_size=16).digest()


def ntriples_document(lines: Sequence[str]) -> bytes:
    return "".join(f"{line} .\n" for line in lines).encode("utf-8")


class Journal:
    """One connection serves every call, under a lock, so appends are serialised and extend one chain; BEGIN
    IMMEDIATE also keeps another process from forking it."""

    def __init__(self, path: Path | None, *, sync_full: bool = False, max_bytes: int = 0) -> None:
        self.path = path
        self.max_bytes = max_bytes
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
        self._connection = sqlite3.connect(
            ":memory:" if path is None else str(path), isolation_level=None, check_same_thread=False, timeout=30
        )
        self._lock = threading.Lock()
        # Writers of other processes (API workers) queue on this lock, which wakes the next one as soon as it is
        # released; SQLite's own busy wait sleeps in steps of up to 100 ms.
        self._writers = None if path is None else FileLock(path.with_name(f"{path.name}.lock"))
        # Digests known to be in the journal since the last clearing, for this epoch: re-published triples
        # then cost no database lookup. Only ever holds digests that were committed.
        self._known: set[bytes] = set()
        self._known_epoch = -1
        self.storage_problem: str | None = None  # why the last write failed for want of space, until one works
        with self._lock:
            if path is not None:
                # WAL: a commit is durable across a crash of the server process. NORMAL sync leaves the newest
                # commits to the operating system's cache on a power cut; FULL syncs every commit (slower).
                self._connection.execute("PRAGMA journal_mode=WAL")
                self._connection.execute(f"PRAGMA synchronous={'FULL' if sync_full else 'NORMAL'}")
            self._connection.executescript(SCHEMA)
            present = {row[1] for row in self._connection.execute("PRAGMA table_info(receipts)")}
            for column, kind in ADDED_COLUMNS.items():
                if column not in present:
                    self._connection.execute(f"ALTER TABLE receipts ADD COLUMN {column} {kind}")

    # --- writing ---------------------------------------------------------------------------------------

    def append_posts(self, posts: Sequence[PostEntry]) -> list[Receipt | BaseException]:
        """Record posts in one transaction, chained in order; each keeps only the triples new to the journal.
        A post that fails alone (its own error) fails alone; a failed commit fails them all, keeping nothing."""
        with self._lock:
            with self._storage_errors(), self._transaction() as connection:
                epoch = self._epoch(connection)
                if epoch != self._known_epoch:
                    self._known, self._known_epoch = set(), epoch
                sequence, previous = self._head(connection)
                outcomes: list[Receipt | BaseException] = []
                for post in posts:
                    connection.execute("SAVEPOINT post")
                    try:
                        receipt, content = self._post_receipt(connection, post, sequence + 1, previous)
                        self._insert(connection, receipt, content)
                    except Exception as error:
                        connection.execute("ROLLBACK TO post")
                        outcomes.append(error)
                        continue
                    finally:
                        connection.execute("RELEASE post")
                    sequence, previous = receipt.sequence, receipt.receipt_hash
                    outcomes.append(receipt)
                self._check_size(connection)
            # Committed: only now may the cache say these triples are in the journal.
            for post, outcome in zip(posts, outcomes, strict=True):
                if isinstance(outcome, Receipt):
                    self._known.update(post.digests)
        return outcomes

    def append_clear(self, *, log_id: str, user: str, claimed_user: str | None) -> Receipt:
        """Record a clearing of the events graph: the journal forgets every triple it held (they may come again),
        and the receipt counts them as removed."""
        with self._lock, self._storage_errors():
            receipt, epoch = self._clear(log_id, user, claimed_user)
            self._known, self._known_epoch = set(), epoch
        return receipt

    def _clear(self, log_id: str, user: str, claimed_user: str | None) -> tuple[Receipt, int]:
        with self._transaction() as connection:
            removed = connection.execute("SELECT COUNT(*) FROM journal_triples").fetchone()[0]
            connection.execute("DELETE FROM journal_triples")
            epoch = self._epoch(connection) + 1
            connection.execute(
                "INSERT INTO journal_state (name, value) VALUES ('epoch', ?) "
                "ON CONFLICT (name) DO UPDATE SET value = excluded.value",
                (epoch,),
            )
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
        self, connection: sqlite3.Connection, post: PostEntry, sequence: int, previous: str
    ) -> tuple[Receipt, bytes]:
        unknown = [index for index, digest in enumerate(post.digests) if digest not in self._known]
        new_digests = _insert_new_digests(connection, [post.digests[index] for index in unknown])
        new_lines = [post.lines[index] for index in unknown if post.digests[index] in new_digests]
        content = ntriples_document(new_lines)
        receipt = Receipt(
            sequence, post.log_id, "ingest", post.user, post.claimed_user, utc_iso(), post.payload_sha256,
            len(post.lines), len(new_lines), 0, hashlib.sha256(content).hexdigest(), previous, "",
        )  # fmt: skip
        return _chained(receipt), content

    def _insert(self, connection: sqlite3.Connection, receipt: Receipt, content: bytes) -> None:
        connection.execute(
            f"INSERT INTO receipts ({COLUMNS}, content) VALUES ({', '.join(['?'] * (len(FIELD_NAMES) + 1))})",
            (*receipt.row(), zlib.compress(content) if content else b""),
        )

    # --- reading ---------------------------------------------------------------------------------------

    def page(self, limit: int, offset: int) -> tuple[list[Receipt], int]:
        """Receipts newest first, and how many there are in all."""
        with self._lock:
            total = self._connection.execute("SELECT COUNT(*) FROM receipts").fetchone()[0]
            rows = self._connection.execute(
                f"SELECT {COLUMNS} FROM receipts ORDER BY sequence DESC LIMIT ? OFFSET ?", (limit, offset)
            ).fetchall()
        return [Receipt(*row) for row in rows], total

    def entry(self, log_id: str) -> tuple[Receipt, bytes | None]:
        """A receipt and its content as received (None for a receipt from before the journal kept content)."""
        with self._lock:
            row = self._connection.execute(
                f"SELECT {COLUMNS}, content FROM receipts WHERE log_id = ?", (log_id,)
            ).fetchone()
        if row is None:
            raise NotFound(f"No receipt with log_id '{log_id}'.")
        receipt = Receipt(*row[:-1])
        return receipt, None if receipt.content_sha256 is None else _inflate(row[-1])

    def age_of(self, sequence: int) -> float:
        """Seconds since entry `sequence` was recorded (0 if there is no such entry)."""
        with self._lock:
            row = self._connection.execute("SELECT recorded_at FROM receipts WHERE sequence = ?", (sequence,))
            found = row.fetchone()
        if found is None:
            return 0.0
        recorded = datetime.fromisoformat(found[0].replace("Z", "+00:00"))
        return max(0.0, (datetime.now(UTC) - recorded).total_seconds())

    def head(self) -> int:
        with self._lock:
            return self._head(self._connection)[0]

    def entries_after(self, sequence: int, limit: int) -> list[JournalEntry]:
        """Up to `limit` entries after `sequence`, oldest first, content decompressed."""
        with self._lock:
            rows = self._connection.execute(
                "SELECT sequence, action, content FROM receipts WHERE sequence > ? ORDER BY sequence LIMIT ?",
                (sequence, limit),
            ).fetchall()
        return [JournalEntry(number, action, _inflate(blob)) for number, action, blob in rows]

    def last_clearing(self) -> int:
        """The sequence of the newest clearing (0 when there was none): the store holds what came after it."""
        with self._lock:
            found = self._connection.execute("SELECT MAX(sequence) FROM receipts WHERE action = 'delete_all'")
            return found.fetchone()[0] or 0

    def received_documents(self, batch_entries: int = 200) -> Iterator[bytes]:
        """The content of every post since the last clearing, oldest first: the events graph as received."""
        position = self.last_clearing()
        while entries := self.entries_after(position, batch_entries):
            for entry in entries:
                if entry.content:
                    yield entry.content
            position = entries[-1].sequence

    def verify(self, *, deep: bool = False) -> Verification:
        """Recompute every hash and link, oldest first (and with `deep`, every content's hash); report the
        first receipt where the chain fails. Runs under the lock, so it checks one consistent state."""
        check = ChainCheck()
        columns = f"{COLUMNS}, content" if deep else COLUMNS
        with self._lock:
            for row in self._connection.execute(f"SELECT {columns} FROM receipts ORDER BY sequence"):
                receipt = Receipt(*row[: len(FIELD_NAMES)])
                content_hash = hashlib.sha256(_inflate(row[-1])).hexdigest() if deep else None
                check.add(receipt, content_hash)
        return Verification(check.count, check.first_broken, deep)

    def close(self) -> None:
        with self._lock:
            self._connection.close()
            if self._writers is not None:
                self._writers.close()

    # --- plumbing --------------------------------------------------------------------------------------

    def _head(self, connection: sqlite3.Connection) -> tuple[int, str]:
        last = connection.execute("SELECT sequence, receipt_hash FROM receipts ORDER BY sequence DESC LIMIT 1")
        row = last.fetchone()
        return (row[0], row[1]) if row else (0, GENESIS_HASH)

    def _epoch(self, connection: sqlite3.Connection) -> int:
        row = connection.execute("SELECT value FROM journal_state WHERE name = 'epoch'").fetchone()
        return row[0] if row else 0

    def _check_size(self, connection: sqlite3.Connection) -> None:
        if not self.max_bytes or self.path is None:
            return
        pages, page_size = (connection.execute(f"PRAGMA {name}").fetchone()[0] for name in ("page_count", "page_size"))
        if pages * page_size > self.max_bytes:
            raise StorageFull(
                f"The journal would grow past {self.max_bytes} bytes (JOURNAL_MAX_BYTES); posts are refused until "
                "the limit is raised or space is freed."
            )

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        # IMMEDIATE takes the write lock up front, so even another process appending cannot fork the chain.
        with self._writers.held() if self._writers is not None else nullcontext():
            self._connection.execute("BEGIN IMMEDIATE")
            try:
                yield self._connection
            except BaseException:
                if self._connection.in_transaction:
                    self._connection.execute("ROLLBACK")
                raise
            self._connection.execute("COMMIT")

    def storage_ok(self) -> bool:
        """Whether the journal can take writes: True unless the last write failed for want of space and the
        disk is still nearly full (so readiness recovers as soon as space returns, before the next post)."""
        if self.storage_problem is None or self.path is None:
            return True
        return shutil.disk_usage(self.path.parent).free > FREE_BYTES_NEEDED and not self._over_quota()

    def _over_quota(self) -> bool:
        return bool(self.max_bytes) and self.path is not None and self.path.stat().st_size > self.max_bytes

    @contextmanager
    def _storage_errors(self) -> Iterator[None]:
        try:
            yield
        except StorageFull as full:
            self.storage_problem = full.message
            raise
        except sqlite3.OperationalError as error:
            if "full" in str(error) or "disk I/O" in str(error):
                where = self.path.parent if self.path else "memory"
                self.storage_problem = f"the disk holding {where} is full ({error})"
                raise StorageFull(
                    f"The journal cannot grow: {self.storage_problem}. Posts are refused until space is freed; "
                    "nothing of this post was kept."
                ) from None
            raise
        self.storage_problem = None


def _chained(receipt: Receipt) -> Receipt:
    return replace(receipt, receipt_hash=receipt.computed_hash())


def _inflate(blob: bytes | None) -> bytes:
    return zlib.decompress(blob) if blob else b""


def _insert_new_digests(connection: sqlite3.Connection, digests: list[bytes]) -> set[bytes]:
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
