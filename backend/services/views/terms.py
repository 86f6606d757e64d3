"""Texts (IRIs, terms) as small integers in a view's database: each text is written once, in a table of terms
(`id`, `hash`, `text`), and every row refers to it by number. A million triples of one robot hold a few hundred
thousand distinct IRIs, each written dozens of times as the subject or object of a link or in a report's row
keys and filters: as numbers, a view is a fraction of the size, and a post's new rows land at the end of the
tables' B-trees instead of at random pages.

A text is found by a 64-bit hash of it (an index of small integers, not of the texts); the text is compared
too, so two texts sharing a hash stay apart. Ids are made only by the view's writer; readers look them up. A
view that empties its terms (a build, a clearing) makes its writer forget the ids it remembered.

A view that never reads a text back from its number (the kept rows: their own values are in their rows; they
only find a text's number, to store it or to filter by it) keeps a table of digests instead (`texts=False`):
the text's 128-bit digest (BLAKE2b) in place of the text, found by its first half and told apart by the other.
Two texts would share a number only if their 128-bit digests were equal: as likely as two of git's object
names colliding. It saves the text itself: 60 to 80 bytes an IRI. Its rows are kept in the order of their
digests (a table keyed by them, so no index of them beside it) and numbered from a count kept beside them
(`{table}_made`), which the writer moves in its own transaction: a writer in another process, later, goes on
from where it stopped.
"""

from __future__ import annotations

import hashlib
import sqlite3
from collections import OrderedDict
from collections.abc import Collection, Iterable

CHUNK = 400  # values per IN (…) list
REMEMBERED = 20_000  # ids the writer remembers (each about 200 bytes): the robot, its models, recent nodes


def iri_hash(iri: str) -> int:
    """A stable 64-bit hash (Python's `hash` changes with every process)."""
    return int.from_bytes(hashlib.blake2b(iri.encode(), digest_size=8).digest(), "big", signed=True)


def iri_digest(iri: str) -> tuple[int, int]:
    """A stable 128-bit digest, as the two signed 64-bit integers SQLite stores."""
    digest = hashlib.blake2b(iri.encode(), digest_size=16).digest()
    return int.from_bytes(digest[:8], "big", signed=True), int.from_bytes(digest[8:], "big", signed=True)


def schema(table: str, *, texts: bool = True) -> list[str]:
    """The statements making a table of terms named `table` (of their digests when not `texts`)."""
    if not texts:
        return [
            f"CREATE TABLE IF NOT EXISTS {table} (hash INTEGER NOT NULL, tail INTEGER NOT NULL, id INTEGER NOT NULL, "
            "PRIMARY KEY (hash, tail)) WITHOUT ROWID",
            f"CREATE TABLE IF NOT EXISTS {table}_made (id INTEGER PRIMARY KEY CHECK (id = 1), made INTEGER NOT NULL)",
            f"INSERT OR IGNORE INTO {table}_made VALUES (1, 0)",
        ]
    return [
        f"CREATE TABLE IF NOT EXISTS {table} (id INTEGER PRIMARY KEY, hash INTEGER NOT NULL, text TEXT NOT NULL)",
        f"CREATE INDEX IF NOT EXISTS {table}_by_hash ON {table} (hash)",
    ]


def tables(table: str, *, texts: bool = True) -> tuple[str, ...]:
    """The tables `schema` makes."""
    return (table,) if texts else (table, f"{table}_made")


class TermIds:
    """The writer's way to ids in the table `table`: remembers the most recently used, makes the missing ones."""

    def __init__(self, table: str, remembered: int = REMEMBERED, *, texts: bool = True) -> None:
        self.table = table
        self.texts = texts
        self._ids: OrderedDict[str, int] = OrderedDict()
        self._remembered = remembered

    def forget(self) -> None:
        self._ids.clear()

    def ids(self, connection: sqlite3.Connection, iris: Iterable[str]) -> dict[str, int]:
        """The id of each text, made for those the table does not hold yet (inside the writer's transaction)."""
        found: dict[str, int] = {}
        missing: list[str] = []
        for iri in dict.fromkeys(iris):
            known = self._ids.get(iri)
            if known is None:
                missing.append(iri)
            else:
                self._ids.move_to_end(iri)
                found[iri] = known
        if missing:
            stored = lookup(connection, self.table, missing, texts=self.texts)
            new = [iri for iri in missing if iri not in stored]
            if new:
                if self.texts:
                    rows = [(iri_hash(iri), iri) for iri in new]
                    connection.executemany(f"INSERT INTO {self.table} (hash, text) VALUES (?, ?)", rows)
                    stored.update(lookup(connection, self.table, new))
                else:
                    stored.update(self._numbered(connection, new))
            found.update(stored)
            for iri in missing:
                self._ids[iri] = stored[iri]
            while len(self._ids) > self._remembered:
                self._ids.popitem(last=False)
        return found

    def _numbered(self, connection: sqlite3.Connection, new: list[str]) -> dict[str, int]:
        """Digests of texts the table does not hold, written with the next numbers of its count."""
        (last,) = connection.execute(
            f"UPDATE {self.table}_made SET made = made + ? RETURNING made - ?", (len(new), len(new))
        ).fetchone()
        numbers = {iri: last + offset for offset, iri in enumerate(new, start=1)}
        connection.executemany(
            f"INSERT INTO {self.table} (hash, tail, id) VALUES (?, ?, ?)",
            [(*iri_digest(iri), number) for iri, number in numbers.items()],
        )
        return numbers


def lookup(connection: sqlite3.Connection, table: str, iris: Collection[str], *, texts: bool = True) -> dict[str, int]:
    """The ids of those texts the table holds (a reader's way: nothing is made); `texts`: as the table was made."""
    if not texts:
        return _lookup_digests(connection, table, iris)
    wanted = set(iris)
    found: dict[str, int] = {}
    hashes = sorted({iri_hash(iri) for iri in wanted})
    for start in range(0, len(hashes), CHUNK):
        chunk = hashes[start : start + CHUNK]
        marks = ", ".join("?" * len(chunk))
        for term_id, iri in connection.execute(f"SELECT id, text FROM {table} WHERE hash IN ({marks})", chunk):
            if iri in wanted:
                found[iri] = term_id
    return found


def _lookup_digests(connection: sqlite3.Connection, table: str, iris: Collection[str]) -> dict[str, int]:
    by_digest = {iri_digest(iri): iri for iri in set(iris)}
    hashes = sorted({head for head, _ in by_digest})
    found: dict[str, int] = {}
    for start in range(0, len(hashes), CHUNK):
        chunk = hashes[start : start + CHUNK]
        marks = ", ".join("?" * len(chunk))
        query = f"SELECT id, hash, tail FROM {table} WHERE hash IN ({marks})"
        for term_id, head, tail in connection.execute(query, chunk):
            iri = by_digest.get((head, tail))
            if iri is not None:
                found[iri] = term_id
    return found


def texts_of(connection: sqlite3.Connection, table: str, ids: Collection[int]) -> dict[int, str]:
    """The text of each id."""
    found: dict[int, str] = {}
    listed = list(ids)
    for start in range(0, len(listed), CHUNK):
        chunk = listed[start : start + CHUNK]
        marks = ", ".join("?" * len(chunk))
        found.update(connection.execute(f"SELECT id, text FROM {table} WHERE id IN ({marks})", chunk).fetchall())
    return found
