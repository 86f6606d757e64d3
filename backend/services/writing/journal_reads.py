"""Reading the journal: receipts, entries for the applier and the views, the content of posts, the erasures'
records, and the verification of the chain. The journal (journal.py) writes; this is what it reads, through a
connection of its own where the database allows one (`Database.reader`): the applier reading the entries just
recorded, and posts asking how far behind the store is, then never wait for the next batch's commit to sync."""

from __future__ import annotations

import threading
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime

from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.writing.receipts import FIELD_NAMES, GENESIS_HASH, ChainCheck, Receipt, Verification
from segb_server.backend.services.writing.redaction import RedactionCheck, RedactionRecord
from segb_server.backend.state.database import Database

COLUMNS = ", ".join(f'"{name}"' for name in FIELD_NAMES)  # quoted: `user` is a reserved word in PostgreSQL
_ROWS_PER_VERIFY = 1000


_ADDED = b"# added in their place\n"  # an N-Triples comment: no line of removed triples can read so


@dataclass(frozen=True)
class JournalEntry:
    """One entry as the applier reads it: its place, what it did, its content (an N-Triples document: a post's
    triples with the lines erasures put in place of removed ones; empty for a clearing or an erasure), and for an
    erasure not yet applied to the store, the lines it removed and those it put in their place."""

    sequence: int
    action: str
    content: bytes
    removed: bytes = b""
    added: bytes = b""


def pending_document(removed: list[bytes], added: list[bytes]) -> bytes:
    """What an erasure keeps for the store until it is applied: the lines to remove, then those to add."""
    document = b"".join(line + b"\n" for line in removed)
    return document + _ADDED + b"".join(line + b"\n" for line in added) if added else document


def _pending(document: bytes) -> tuple[bytes, bytes]:
    removed, _, added = document.partition(_ADDED)
    return removed, added


class JournalReads:
    """The journal's reads; `_reads` is the journal's reading connection, each call's statements under `_reads_lock`."""

    _reads: Database
    _reads_lock: threading.Lock
    _recorded: dict[int, float]  # the journal's own latest entries: when this process recorded them

    def page(self, limit: int, offset: int) -> tuple[list[Receipt], int]:
        """Receipts newest first, and how many there are in all."""
        with self._reads_lock, self._reads.reading():  # the count and the page of one state
            total = self._reads.execute("SELECT COUNT(*) FROM receipts").fetchone()[0]
            rows = self._reads.execute(
                f"SELECT {COLUMNS} FROM receipts ORDER BY sequence DESC LIMIT ? OFFSET ?", (limit, offset)
            ).fetchall()
        return [Receipt(*row) for row in rows], total

    def entry(self, log_id: str) -> tuple[Receipt, bytes | None]:
        """A receipt and its content as received (None for a receipt from before the journal kept content)."""
        with self._reads_lock:
            row = self._reads.execute(f"SELECT {COLUMNS}, content FROM receipts WHERE log_id = ?", (log_id,)).fetchone()
        if row is None:
            raise NotFound(f"No receipt with log_id '{log_id}'.")
        receipt = Receipt(*row[:-1])
        return receipt, None if receipt.content_sha256 is None else inflate(row[-1])

    def age_of(self, sequence: int) -> float:
        """Seconds since entry `sequence` was recorded (0 if there is no such entry)."""
        known = self._recorded.get(sequence)
        if known is not None:
            return max(0.0, time.time() - known)
        with self._reads_lock:
            row = self._reads.execute("SELECT recorded_at FROM receipts WHERE sequence = ?", (sequence,))
            found = row.fetchone()
        if found is None:
            return 0.0
        recorded = datetime.fromisoformat(found[0].replace("Z", "+00:00"))
        return max(0.0, (datetime.now(UTC) - recorded).total_seconds())

    def head(self) -> int:
        with self._reads_lock:
            return self._head(self._reads)[0]

    def entries_after(self, sequence: int, limit: int) -> list[JournalEntry]:
        """Up to `limit` entries after `sequence`, oldest first, content decompressed."""
        with self._reads_lock:
            rows = self._reads.execute(
                "SELECT r.sequence, r.action, r.content, r.replacements, p.content FROM receipts r "
                "LEFT JOIN erasure_pending p ON p.sequence = r.sequence WHERE r.sequence > ? "
                "ORDER BY r.sequence LIMIT ?",
                (sequence, limit),
            ).fetchall()
        return [
            JournalEntry(
                number,
                action,
                inflate(blob) + inflate(replaced) if action == "ingest" else b"",
                *_pending(inflate(pending)),
            )
            for number, action, blob, replaced, pending in rows
        ]

    def last_clearing(self) -> int:
        """The sequence of the newest clearing (0 when there was none): the store holds what came after it."""
        with self._reads_lock:
            found = self._reads.execute("SELECT MAX(sequence) FROM receipts WHERE action = 'delete_all'")
            return found.fetchone()[0] or 0

    def last_applied_erasure(self) -> int:
        """The newest erasure the store has applied, as far as the journal knows (its removed lines are no
        longer kept); 0 when there is none."""
        with self._reads_lock:
            found = self._reads.execute(
                "SELECT MAX(sequence) FROM receipts WHERE action = 'erase' "
                "AND sequence NOT IN (SELECT sequence FROM erasure_pending)"
            )
            return found.fetchone()[0] or 0

    def received_documents(self, batch_entries: int = 200) -> Iterator[bytes]:
        """The content of every post since the last clearing, oldest first: the events graph as received."""
        position = self.last_clearing()
        while entries := self.entries_after(position, batch_entries):
            for entry in entries:
                if entry.content:
                    yield entry.content
            position = entries[-1].sequence

    def posts_since_clearing(self, batch: int = 200) -> Iterator[tuple[Receipt, bytes, bytes]]:
        """Every post since the last clearing, oldest first: its receipt, its content and the digests of the
        lines erasures removed from it."""
        position = self.last_clearing()
        query = (
            f"SELECT {COLUMNS}, content, redacted_digests FROM receipts WHERE sequence > ? AND action = 'ingest' "
            "ORDER BY sequence LIMIT ?"
        )
        while True:
            with self._reads_lock:
                rows = self._reads.execute(query, (position, batch)).fetchall()
            if not rows:
                return
            for row in rows:
                yield Receipt(*row[: len(FIELD_NAMES)]), inflate(row[-2]), bytes(row[-1] or b"")
            position = rows[-1][0]

    def receipts_after(self, sequence: int, batch: int = 1000) -> Iterator[Receipt]:
        """Every receipt after `sequence`, oldest first."""
        position = sequence
        while True:
            with self._reads_lock:
                rows = self._reads.execute(
                    f"SELECT {COLUMNS} FROM receipts WHERE sequence > ? ORDER BY sequence LIMIT ?", (position, batch)
                ).fetchall()
            if not rows:
                return
            yield from (Receipt(*row) for row in rows)
            position = rows[-1][0]

    def redaction_records(self) -> list[tuple[Receipt, RedactionRecord]]:
        """Every erasure's receipt and record, oldest first."""
        with self._reads_lock:
            rows = self._reads.execute(
                f"SELECT {COLUMNS}, content FROM receipts WHERE action = 'erase' ORDER BY sequence"
            ).fetchall()
        return [(Receipt(*row[:-1]), RedactionRecord.parse(inflate(row[-1]))) for row in rows]

    def verify(self, *, deep: bool = False) -> Verification:
        """Recompute every hash and link, oldest first (and with `deep`, every content's digests, redacted ones
        against the erasures' records); report the first receipt where the chain fails. Reads one consistent
        state, in batches (a whole journal's content would not fit in memory)."""
        check = ChainCheck()
        columns = f"{COLUMNS}, content, redacted_digests, replacements" if deep else COLUMNS
        query = f"SELECT {columns} FROM receipts WHERE sequence > ? ORDER BY sequence LIMIT {_ROWS_PER_VERIFY}"
        with self._reads_lock, self._reads.reading():
            records = [
                (sequence, RedactionRecord.parse(inflate(blob)))
                for sequence, blob in self._reads.execute(
                    "SELECT sequence, content FROM receipts WHERE action = 'erase'"
                ).fetchall()
            ]
            redactions = RedactionCheck(records)
            position = 0
            while rows := self._reads.execute(query, (position,)).fetchall():
                for row in rows:
                    receipt = Receipt(*row[: len(FIELD_NAMES)])
                    fault = (
                        redactions.fault(receipt, inflate(row[-3]), row[-2] or b"", inflate(row[-1])) if deep else None
                    )
                    check.add(receipt, fault)
                position = rows[-1][0]
        return Verification(check.count, check.first_broken, deep, len(records))

    def _head(self, connection: Database) -> tuple[int, str]:
        last = connection.execute("SELECT sequence, receipt_hash FROM receipts ORDER BY sequence DESC LIMIT 1")
        row = last.fetchone()
        return (row[0], row[1]) if row else (0, GENESIS_HASH)


def inflate(blob: bytes | None) -> bytes:
    return zlib.decompress(blob) if blob else b""
