"""Kept rows compressed against a dictionary of their own table's rows.

A report's rows repeat each other: the same robot, models and people, the same IRI prefixes, the same JSON
shape. One robot's month of rows were the biggest part of the views' files (a conversation's row 318 bytes,
a timeline message's 384). Each row is compressed alone, so it is still read and replaced alone, with
zlib's preset dictionary: a sample of the table's own rows, which a row's text mostly repeats (42 and 45
bytes).

A table's rows are stored as plain text until it holds `SAMPLE_ROWS`; its dictionary is then made from them
and every later row is compressed against it. A stored row is therefore either text (plain) or bytes: the
number of its dictionary (a varint) and the raw deflate stream. Dictionary numbers are never reused (an
AUTOINCREMENT key), so a reader in another process that remembers one can never read a row with the wrong
dictionary.

A dictionary quotes rows, so it holds what they hold (names, what people said): it goes with its table's rows
whenever they go (a build drops the table, a clearing empties it, an erasure builds every view again), never
outliving them.
"""

from __future__ import annotations

import sqlite3
import threading
import zlib
from collections import OrderedDict
from collections.abc import Collection, Sequence

from segb_server.backend.services.views.kept_queries import per_table

DICTIONARIES = "report_dictionaries"
SAMPLE_ROWS = 64  # rows a table holds before its dictionary is made from them
SAMPLE_BYTES = 32_768  # zlib's window: a longer dictionary's start is never reached
REMEMBERED = 64  # dictionaries a reader keeps at hand (each at most SAMPLE_BYTES, with its decoder's state)
LEVEL = 9  # a row is a few hundred bytes: the best compression costs tens of microseconds
WINDOW_BITS = -15  # raw deflate: no zlib header and checksum (6 bytes of a 40-byte row)
# zlib's memory level for the compressor (1-9; 8 is its default). Each row compresses on a copy of the primed
# compressor, whose buffers this level sizes. Measured on one robot's rows: the same bytes out at 5 as at 8, about
# 10% less time in a soak's flow, and 20 µs a row instead of 120 with one conversations table's dictionary.
# Decoding does not depend on it: rows written at any level read alike.
MEMORY_LEVEL = 5


def schema() -> list[str]:
    return [
        f"CREATE TABLE IF NOT EXISTS {DICTIONARIES} (id INTEGER PRIMARY KEY AUTOINCREMENT, tab TEXT NOT NULL, "
        "sample BLOB NOT NULL)",
        f"CREATE INDEX IF NOT EXISTS {DICTIONARIES}_by_table ON {DICTIONARIES} (tab)",
    ]


class RowCodec:
    """Writes rows compressed (the views' writer, inside its transaction) and reads them back (any thread)."""

    def __init__(self) -> None:
        self._compressors: dict[str, tuple[int, zlib._Compress]] = {}  # the writer's: table → its dictionary
        self._samples: OrderedDict[int, bytes] = OrderedDict()  # readers': dictionary number → its sample
        self._lock = threading.Lock()  # readers are the server's threads

    # --- writing (the writer's thread) -------------------------------------------------------------------

    def encode(self, connection: sqlite3.Connection, table: str, texts: Sequence[str]) -> list[str | bytes]:
        """`texts` (rows of `table`) as they are stored: compressed once the table has its dictionary, which
        is made here from its first rows when there are enough of them."""
        if not texts:  # a replacement that only removed rows: nothing to look up
            return []
        compressor = self._compressors.get(table) or self._load_or_make(connection, table, texts)
        if compressor is None:
            return list(texts)
        number, primed = compressor
        head = _varint(number)
        stored: list[str | bytes] = []
        for text in texts:
            copy = primed.copy()  # primed with the dictionary once: a copy costs a fraction of priming again
            stored.append(head + copy.compress(text.encode()) + copy.flush())
        return stored

    def _load_or_make(
        self, connection: sqlite3.Connection, table: str, texts: Sequence[str]
    ) -> tuple[int, zlib._Compress] | None:
        found = connection.execute(
            f"SELECT id, sample FROM {DICTIONARIES} WHERE tab = ? ORDER BY id DESC LIMIT 1", (table,)
        ).fetchone()
        if found is None:
            kept = [row[0] for row in connection.execute(f"SELECT row FROM {table} LIMIT ?", (SAMPLE_ROWS,))]
            rows = [text for text in [*kept, *texts] if isinstance(text, str)]
            if len(rows) < SAMPLE_ROWS:
                return None
            sample = "".join(rows).encode()[-SAMPLE_BYTES:]
            cursor = connection.execute(f"INSERT INTO {DICTIONARIES} (tab, sample) VALUES (?, ?)", (table, sample))
            found = (cursor.lastrowid, sample)
        number, sample = int(found[0]), bytes(found[1])
        compressor = (number, zlib.compressobj(LEVEL, zlib.DEFLATED, WINDOW_BITS, MEMORY_LEVEL, zdict=sample))
        self._compressors[table] = compressor
        return compressor

    def forget(self, connection: sqlite3.Connection, tables: Collection[str] | None = None) -> None:
        """The dictionaries of `tables` (of every table: None) go, with the rows they were made from; inside
        the writer's transaction that empties or drops those tables."""
        per_table.forget(connection, DICTIONARIES, self._compressors, tables)

    def forget_made(self) -> None:
        """The writer's transaction rolled back: the dictionaries it remembers are read (or made) again."""
        self._compressors.clear()

    def keep_only(self, connection: sqlite3.Connection, tables: Collection[str]) -> None:
        """The dictionaries of tables but `tables` go (those tables were dropped)."""
        self.forget(connection, per_table.dropped(connection, DICTIONARIES, tables))

    # --- reading -----------------------------------------------------------------------------------------

    def decode(self, connection: sqlite3.Connection, stored: str | bytes) -> str:
        """A stored row's text."""
        if isinstance(stored, str):
            return stored
        number, start = _read_varint(stored)
        decoder = zlib.decompressobj(WINDOW_BITS, zdict=self._sample(connection, number))
        return (decoder.decompress(stored[start:]) + decoder.flush()).decode()

    def _sample(self, connection: sqlite3.Connection, number: int) -> bytes:
        with self._lock:
            sample = self._samples.get(number)
            if sample is not None:
                self._samples.move_to_end(number)
                return sample
        found = connection.execute(f"SELECT sample FROM {DICTIONARIES} WHERE id = ?", (number,)).fetchone()
        if found is None:  # its table was dropped or emptied after this row was read: a row no longer kept
            raise LookupError(f"row dictionary {number} is no longer kept")
        sample = bytes(found[0])
        with self._lock:
            self._samples[number] = sample
            while len(self._samples) > REMEMBERED:
                self._samples.popitem(last=False)
        return sample


def _varint(number: int) -> bytes:
    out = bytearray()
    while True:
        low, number = number & 0x7F, number >> 7
        out.append(low | (0x80 if number else 0))
        if not number:
            return bytes(out)


def _read_varint(data: bytes) -> tuple[int, int]:
    number, shift, index = 0, 0, 0
    while True:
        byte = data[index]
        number |= (byte & 0x7F) << shift
        index += 1
        if not byte & 0x80:
            return number, index
        shift += 7
