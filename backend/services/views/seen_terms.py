"""The IRIs the store has held a triple about, so that the views can tell a batch's fresh resources.

An IRI no triple of the store mentioned before a batch is `fresh` in it: every triple the store holds about it
is one of the batch's (or of a later batch's, which the views see in their turn). A post of a robot that runs
for months mostly introduces such resources (the activity, its message, the visitor), and the views follow
the joins from them among the batch's own triples instead of asking the store (`kept_queries/delta_joins.py`).

Kept as 64-bit hashes (`terms.iri_hash`) in a SQLite file beside the views, with the journal sequence it
includes: two IRIs sharing a hash only make one of them look seen, which costs a store query and never an
answer. What the registry holds must include every IRI of the store through that sequence before a view is
told a term is fresh, so it is written before the views of a batch, built from the store when absent, caught
up from the journal at start, emptied by a clearing (the store then holds nothing older) and built again after
an erasure (the hashes of erased IRIs go with them).
"""

from __future__ import annotations

import logging
import sqlite3
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

from pyoxigraph import NamedNode, Quad

from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.terms import CHUNK, iri_hash
from segb_server.backend.store.base import Store
from segb_server.backend.store.terms import term_text

logger = logging.getLogger("segb.views")

SEEN_TERMS_FILE = "seen-terms.sqlite3"  # in the data directory, beside the views
VERSION = "1"  # what the file holds and how; another version is built again
BUILD_BATCH = 20_000  # quads read from the store at a time when building

SCHEMA = [
    "CREATE TABLE IF NOT EXISTS seen (hash INTEGER PRIMARY KEY) WITHOUT ROWID",
    "CREATE TABLE IF NOT EXISTS seen_state (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
]


class SeenTerms:
    def __init__(self, path: Path | None) -> None:
        self.db = ViewDatabase(path, SCHEMA)

    def stored_through(self) -> int | None:
        """The journal sequence the registry includes; None when it must be built (absent, another version)."""
        return self._through(self.db.reader())

    def build(self, store: Store, through: int) -> None:
        """Every IRI of the store (which holds the journal through `through`, or more: an IRI of a later step only
        looks seen early)."""
        started = time.perf_counter()
        with self.db.writing() as connection:
            connection.execute("DELETE FROM seen")
            connection.execute("DELETE FROM seen_state")
        count = 0
        for quads in store.batches(BUILD_BATCH):
            with self.db.writing() as connection:
                _insert(connection, _iris(quads))
            count += len(quads)
        self._set_through(through)
        logger.info("the store's IRIs registered from %d triples in %.1f s", count, time.perf_counter() - started)

    def clear(self, through: int) -> None:
        """The graph was emptied at `through`: nothing the store holds is older."""
        with self.db.writing() as connection:
            connection.execute("DELETE FROM seen")
        self._set_through(through)

    def admit(self, quads: Sequence[Quad], first: int, through: int) -> frozenset[str]:
        """Register the IRIs of the steps `first`..`through` (their triples `quads`); returns those the store held
        no triple about before `first` (N-Triples texts). None is returned fresh when the registry does not
        include every step before `first`: it could miss what they mentioned."""
        iris = _iris(quads)
        with self.db.writing() as connection:
            stored = self._through(connection)
            seen = _seen(connection, iris.keys()) if stored is not None and stored >= first - 1 else None
            _insert(connection, iris)
            if stored is not None:  # an unbuilt registry stays unbuilt: it holds only some of the store's IRIs
                connection.execute(
                    "INSERT OR REPLACE INTO seen_state (key, value) VALUES ('through', ?)", (str(max(stored, through)),)
                )
        if seen is None:
            return frozenset()
        return frozenset(text for digest, texts in iris.items() if digest not in seen for text in texts)

    def close(self) -> None:
        self.db.close()

    def _set_through(self, through: int) -> None:
        with self.db.writing() as connection:
            connection.executemany(
                "INSERT OR REPLACE INTO seen_state (key, value) VALUES (?, ?)",
                [("version", VERSION), ("through", str(through))],
            )

    @staticmethod
    def _through(connection: sqlite3.Connection) -> int | None:
        rows = dict(connection.execute("SELECT key, value FROM seen_state").fetchall())
        if rows.get("version") != VERSION or "through" not in rows:
            return None
        return int(rows["through"])


def _iris(quads: Iterable[Quad]) -> dict[int, set[str]]:
    """The quads' subject and object IRIs by hash (blank nodes are never fresh: their labels are the store's)."""
    found: dict[int, set[str]] = {}
    for quad in quads:
        for term in (quad.subject, quad.object):
            if isinstance(term, NamedNode):
                text = term_text(term)
                found.setdefault(iri_hash(text), set()).add(text)
    return found


def _seen(connection: sqlite3.Connection, digests: Iterable[int]) -> set[int]:
    listed = sorted(digests)
    seen: set[int] = set()
    for start in range(0, len(listed), CHUNK):
        chunk = listed[start : start + CHUNK]
        marks = ", ".join("?" * len(chunk))
        rows = connection.execute(f"SELECT hash FROM seen WHERE hash IN ({marks})", chunk)
        seen.update(digest for (digest,) in rows)
    return seen


def _insert(connection: sqlite3.Connection, iris: dict[int, set[str]]) -> None:
    connection.executemany("INSERT OR IGNORE INTO seen (hash) VALUES (?)", [(digest,) for digest in iris])
