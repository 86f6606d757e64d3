"""IRIs in a table's sort keys written without their namespace, in the same order: a dictionary per table.

A kept row's sort key spells the IRIs the report sorts by (a conversation's: its robot, its visitor, its
message), and a plain report's indexes hold the key's head again (its robot and visitor, then its time): one
robot's month of conversations spent more bytes on those IRIs' shared namespaces than on anything else. Each
table therefore has a sorted list of namespaces, made from the IRIs of the first rows it is given, and an IRI in
its keys is written as the place of the greatest namespace not after it (`RANK_DIGITS` digits), then either
`1` and what follows that namespace (when the IRI begins with it) or `2` and the whole IRI.

Why the order is kept, for IRIs s < t with the same greatest namespace n ≤ them: those beginning with n are
n's extensions, ordered as what follows n; one that does not begin with n yet is not before n differs from n
at some character, where it is greater, so it sorts after every extension of n, and those are ordered as
themselves. Namespaces of lower places sort before, of higher places after. An encoded IRI that is a prefix of
another stands for a prefix of the other's IRI, so a shorter value still sorts first.

A table's namespaces never change while it has rows: they are made with its first rows (a build's first batch,
or the first post that gives it one) and go with its rows, like its rows' dictionary (`row_codec.py`). Numbers
are never reused (AUTOINCREMENT), so a reader that remembers one never encodes with another table version's.
A namespace can name a person (`…/people/alice/`): it goes with the rows it was taken from, and an erasure drops
them all.
"""

from __future__ import annotations

import json
import sqlite3
import threading
from bisect import bisect_right
from collections import Counter
from collections.abc import Collection, Iterable
from dataclasses import dataclass

from segb_server.backend.services.views.kept_queries import per_table

KEY_NAMESPACES = "report_key_namespaces"
ORDER_DIGITS = "-0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ_abcdefghijklmnopqrstuvwxyz"  # 64 digits, in byte order
RANK_DIGITS = 2
MAX_NAMESPACES = len(ORDER_DIGITS) ** RANK_DIGITS - 1  # place 0: before every namespace
SHORTEST_NAMESPACE = 12  # a shorter one saves less than it costs to look up
REMEMBERED = 256  # versions of tables' namespaces a reader keeps parsed


def schema() -> list[str]:
    return [
        f"CREATE TABLE IF NOT EXISTS {KEY_NAMESPACES} (id INTEGER PRIMARY KEY AUTOINCREMENT, tab TEXT NOT NULL, "
        "namespaces TEXT NOT NULL)",
        f"CREATE INDEX IF NOT EXISTS {KEY_NAMESPACES}_by_table ON {KEY_NAMESPACES} (tab)",
    ]


def order_digits(number: int, width: int) -> str:
    """`number` as `width` digits of ORDER_DIGITS: fixed-width texts that sort as their numbers."""
    digits = []
    for _ in range(width):
        number, digit = divmod(number, len(ORDER_DIGITS))
        digits.append(ORDER_DIGITS[digit])
    if number:
        raise ValueError("too large for its width")
    return "".join(reversed(digits))


def number_of(digits: str) -> int:
    number = 0
    for digit in digits:
        number = number * len(ORDER_DIGITS) + ORDER_DIGITS.index(digit)
    return number


@dataclass(frozen=True)
class Namespaces:
    """One table's namespaces, sorted."""

    entries: tuple[str, ...] = ()

    def iri_part(self, iri: str) -> str:
        """How `iri` is written in a sort key of this table (after the IRIs' kind). Without namespaces every IRI
        would be written after the same three characters: it is written whole."""
        if not self.entries:
            return iri
        place = bisect_right(self.entries, iri)  # how many namespaces are not after it
        rank = order_digits(place, RANK_DIGITS)
        if place and iri.startswith(self.entries[place - 1]):
            return rank + "1" + iri[len(self.entries[place - 1]) :]
        return rank + "2" + iri

    @staticmethod
    def made_from(iris: Iterable[str]) -> Namespaces:
        """The namespaces (up to a last `/` or `#`) of these IRIs, the most frequent first when there are more
        than a table may have."""
        counted = Counter(namespace_of(iri) for iri in iris)
        kept = [name for name, _ in counted.most_common() if len(name) >= SHORTEST_NAMESPACE]
        return Namespaces(tuple(sorted(kept[:MAX_NAMESPACES])))


def namespace_of(iri: str) -> str:
    return iri[: max(iri.rfind("/"), iri.rfind("#")) + 1]


class KeyNamespaces:
    """Each table's namespaces: made and remembered by the views' writer, read by any thread."""

    def __init__(self) -> None:
        self._writing: dict[str, Namespaces] = {}  # the writer's: table → its namespaces
        self._read: dict[int, Namespaces] = {}  # readers': number → namespaces (a handful of tables)
        self._lock = threading.Lock()

    def for_writing(self, connection: sqlite3.Connection, table: str, iris: Iterable[str]) -> Namespaces:
        """The table's namespaces, made here from `iris` (those of the rows being written) when it has none."""
        kept = self._writing.get(table)
        if kept is not None:
            return kept
        found = connection.execute(
            f"SELECT namespaces FROM {KEY_NAMESPACES} WHERE tab = ? ORDER BY id DESC LIMIT 1", (table,)
        ).fetchone()
        if found is not None:
            kept = Namespaces(tuple(json.loads(found[0])))
        else:
            kept = Namespaces.made_from(iris)
            connection.execute(
                f"INSERT INTO {KEY_NAMESPACES} (tab, namespaces) VALUES (?, ?)", (table, json.dumps(kept.entries))
            )
        self._writing[table] = kept
        return kept

    def for_reading(self, connection: sqlite3.Connection, table: str) -> Namespaces:
        """The namespaces the table's keys were written with (none while it has no rows)."""
        found = connection.execute(
            f"SELECT id, namespaces FROM {KEY_NAMESPACES} WHERE tab = ? ORDER BY id DESC LIMIT 1", (table,)
        ).fetchone()
        if found is None:
            return Namespaces()
        number = int(found[0])
        with self._lock:
            kept = self._read.get(number)
            if kept is None:
                if len(self._read) >= REMEMBERED:  # tables built again many times: older versions go
                    self._read.clear()
                kept = self._read[number] = Namespaces(tuple(json.loads(found[1])))
        return kept

    def forget(self, connection: sqlite3.Connection, tables: Collection[str] | None = None) -> None:
        """The namespaces of `tables` (of every table: None) go with their rows."""
        per_table.forget(connection, KEY_NAMESPACES, self._writing, tables)

    def forget_made(self) -> None:
        """The writer's transaction rolled back: the namespaces it remembers are read (or made) again."""
        self._writing.clear()

    def keep_only(self, connection: sqlite3.Connection, tables: Collection[str]) -> None:
        self.forget(connection, per_table.dropped(connection, KEY_NAMESPACES, tables))
