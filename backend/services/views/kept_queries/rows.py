"""The rows of materialised reports, in SQLite: replaced key by key as the graph changes, read page by page
with the report's filters as indexed comparisons and its order as an index (keyset paging).

A plain report keeps its rows as its query gives them. An aggregate report keeps its contributions (the rows
before grouping, one unit per value of its COUNT(DISTINCT …) argument), so filters that apply before grouping
(a time window) stay exact when a filtered page groups them as it is read. Its unfiltered pages, the ones every
visit opens with, read its groups: each group's aggregates kept in a table of their own, computed again for
the groups a replacement touches, so a first page costs its own rows however many contributions there are.
A MIN and a MAX of one variable share their contributions' column and its index.

A facet filter's pairs (`facets.py`) are kept in a table named by the facet's patterns, shared by every report
of the database whose facet has the same ones (the timeline's kinds of activity).

Compact on disk (a million triples of one robot: its rows were as big as the store itself): a row's key (unit),
the IRIs its filters compare and its facets are numbers from the database's table of terms (`views/terms.py`);
a row is stored as the JSON list of its values, compressed against a dictionary of its table's first rows
(`row_codec.py`: 6 to 8 times smaller); a sort key writes its IRIs without the table's namespaces and its
times as 10 characters (`key_namespaces.py`, `encoding.py`: a conversation's key 75 bytes, was 200); a filter
on the first column the report sorts by (a robot, in the conversations) is a range of the sort key's index
rather than an index of its own. A plain report's indexes (its order, its filters) hold the head of the sort
key (`head_of`: a message's time) rather than the whole key (its time and the IRIs that break ties, once in
each index); a page is chosen by its heads and its rows then put in the whole key's order (`_head_page`).
"""

from __future__ import annotations

import base64
import json
import struct
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import orjson
from pyoxigraph import NamedNode

from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.sparql.catalog import Parameter
from segb_server.backend.services.values import JsonValue, iso_time, json_value
from segb_server.backend.services.views import terms
from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.kept_queries import key_namespaces, row_codec
from segb_server.backend.services.views.kept_queries.encoding import (
    SEPARATOR,
    filter_value,
    instant_of_part,
    sort_key,
)
from segb_server.backend.services.views.kept_queries.facets import FACETS_PREFIX
from segb_server.backend.services.views.kept_queries.key_namespaces import KEY_NAMESPACES, KeyNamespaces, Namespaces
from segb_server.backend.services.views.kept_queries.plan import ReportPlan
from segb_server.backend.services.views.kept_queries.row_codec import DICTIONARIES, RowCodec
from segb_server.backend.services.views.signal import ChangeSignal
from segb_server.backend.services.views.terms import TermIds
from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text

Row = dict[str, Term]  # one solution: variable name (without ?) → term


@dataclass(frozen=True)
class Page:
    rows: list[dict[str, JsonValue]]
    has_more: bool
    after: str | None  # cursor of the last row, for the next page
    last_event_id: int = 0  # the last change (of `GET /reports/stream`) these rows are known to include


@dataclass(frozen=True)
class Layout:
    """How one report's rows are stored: its table and the filter columns it indexes."""

    table: str
    plan: ReportPlan
    parameters: dict[str, Parameter]
    unit: str  # the variable (without ?) whose values are the rows' keys
    # facet parameter → the table of its (value, anchor) pairs, shared by every report of this database whose
    # facet has the same patterns (`facets.facet_table`: the timeline's kinds share theirs)
    facet_tables: Mapping[str, str] = field(default_factory=dict)

    @cached_property
    def filter_columns(self) -> dict[str, str]:
        """Column variable (without ?) → SQL column, for each column a filter compares from a column of its own
        (a filter on the first column of the sort key compares the sort key: `sorted_by`)."""
        return {f.column[1:]: f"f_{f.column[1:]}" for f in self.plan.column_filters if f.column[1:] != self.sorted_by}

    @cached_property
    def sorted_by(self) -> str | None:
        """The first variable of the sort key, when an equality filter on an IRI compares it: rows of one value
        are then one range of the sort key, read from its index."""
        order = self.plan.group_by if self.plan.is_aggregate else self.plan.order
        first = order[0] if order else None
        for condition in self.plan.column_filters:
            if condition.column == first and condition.op == "=" and self.parameters[condition.parameter].type == "iri":
                return first[1:]
        return None

    @cached_property
    def anchors(self) -> dict[str, str]:
        """Anchor variable → SQL column: the filter column of the same variable when it holds the IRI's term."""
        columns = self.filter_columns
        return {
            f.anchor[1:]: columns[f.anchor[1:]] if self._term_column(f.anchor[1:]) else f"a_{f.anchor[1:]}"
            for f in self.plan.facet_filters
        }

    def _term_column(self, variable: str) -> bool:
        return variable in self.filter_columns and self.kind_of(variable) == "iri"

    def kind_of(self, column: str) -> str:
        return self._kinds[column]

    @cached_property
    def _kinds(self) -> dict[str, str]:
        return {f.column[1:]: self.parameters[f.parameter].type for f in self.plan.column_filters}

    @cached_property
    def own_anchors(self) -> dict[str, str]:
        """The anchors stored in columns of their own."""
        return {var: sql for var, sql in self.anchors.items() if not self._term_column(var)}

    @property
    def indexes_head(self) -> bool:
        """Whether the indexes hold the sort key's head rather than the whole key: a plain report's do; an
        aggregate's filtered pages group their contributions by the whole key, read in its order from the
        filter's index, and its groups are found by the whole key."""
        return not self.plan.is_aggregate

    @property
    def order_column(self) -> str:
        """What the indexes order rows by: the head, or the whole sort key."""
        return HEAD if self.indexes_head else "ord"

    @property
    def column_count(self) -> int:
        aggregates = len(self.argument_columns) if self.plan.is_aggregate else 0
        return 4 + self.indexes_head + len(self.filter_columns) + len(self.own_anchors) + aggregates

    @cached_property
    def argument_column(self) -> list[int]:
        """For each aggregate, the column `g_<n>` its argument is kept in: a MIN and a MAX of one variable (a
        person's first and last visit) read the same values, from one column and one index (read from either
        end)."""
        extremes = ("min", "max")
        return [next(earlier for earlier, other in enumerate(self.plan.aggregates[: index + 1])
                     if earlier == index or (aggregate.function in extremes and other.function in extremes
                                             and other.argument == aggregate.argument))
                for index, aggregate in enumerate(self.plan.aggregates)]  # fmt: skip

    @property
    def argument_columns(self) -> list[int]:
        """The `g_<n>` columns a contribution keeps, each once."""
        return list(dict.fromkeys(self.argument_column))

    def schema(self) -> list[str]:
        types = {"decimal": "REAL", "integer": "REAL", "dateTime": "INTEGER", "iri": "INTEGER"}
        filters = [f"{sql} {types.get(self.kind_of(var), 'TEXT')}" for var, sql in self.filter_columns.items()]
        anchors = [f"{sql} INTEGER" for sql in self.own_anchors.values()]
        aggregate = [f"g_{i}" for i in self.argument_columns] if self.plan.is_aggregate else []
        head = ["head_length INTEGER"] if self.indexes_head else []
        columns = ", ".join(["unit INTEGER", "n INTEGER", "ord TEXT", "row TEXT", *head, *filters, *anchors,
                             *aggregate])  # fmt: skip
        statements = [
            f"CREATE TABLE IF NOT EXISTS {self.table} ({columns}, PRIMARY KEY (unit, n))",
            f"CREATE INDEX IF NOT EXISTS {self.table}_ord ON {self.table} ({self.order_column}, unit, n)",
            *(f"CREATE TABLE IF NOT EXISTS {facets} (value INTEGER, anchor INTEGER, PRIMARY KEY (value, anchor)) "
              "WITHOUT ROWID" for facets in sorted(set(self.facet_tables.values()))),
        ]  # fmt: skip
        for sql in dict.fromkeys([*self.filter_columns.values(), *self.anchors.values()]):
            # The sort key (or its head): a filtered page is chosen from this index alone (see `page`).
            statements.append(
                f"CREATE INDEX IF NOT EXISTS {self.table}_{sql} ON {self.table} ({sql}, {self.order_column}, unit, n)"
            )
        if self.plan.is_aggregate:
            for index, kept in enumerate(self.plan.aggregates):
                # a group's extreme is read from its index (`_regroup`), one index a column
                if kept.function != "count" and self.argument_column[index] == index:
                    statements.append(
                        f"CREATE INDEX IF NOT EXISTS {self.table}_g{index} ON {self.table} (ord, g_{index})"
                    )
            values = ", ".join(f"v_{i}" for i in range(len(self.plan.aggregates)))
            statements.append(
                f"CREATE TABLE IF NOT EXISTS {self.table}_groups (ord TEXT PRIMARY KEY, row TEXT, {values}) "
                "WITHOUT ROWID"
            )
        return statements

    @property
    def own_tables(self) -> list[str]:
        """The tables of this report's rows alone."""
        return [self.table, *([f"{self.table}_groups"] if self.plan.is_aggregate else [])]

    @property
    def tables(self) -> list[str]:
        """Every table this report reads: its own and its facets' (shared)."""
        return [*self.own_tables, *sorted(set(self.facet_tables.values()))]

    def grouped(self) -> str:
        """The SELECT list of a group: its order, its sample row, each aggregate over its contributions."""
        aggregates = ", ".join(_sql_aggregate(aggregate.function, aggregate.distinct, f"g_{column}")
                               for aggregate, column in zip(self.plan.aggregates, self.argument_column,
                                                            strict=True))  # fmt: skip
        return f"ord, MIN(row), {aggregates}"

    def texts(self, row: Row) -> list[str]:
        """The texts a stored row refers to by number: the IRIs its filters compare and its anchors."""
        found = [term_text(row[var]) for var in self.filter_columns if self.kind_of(var) == "iri" and _named(row, var)]
        return found + [term_text(row[var]) for var in self.own_anchors if var in row]

    def record(
        self, unit: int, index: int, row: Row, ids: dict[str, int], namespaces: Namespaces
    ) -> tuple[object, ...]:
        """One stored row: its unit, place, sort key, values, filter values, anchors, aggregate arguments."""
        plan = self.plan
        key = sort_key([row.get(name[1:]) for name in self.order], namespaces)
        stored = _row_text([_stored(row.get(name[1:])) for name in self.stored_columns()])
        values: list[object] = [unit, index, key, stored]
        if self.indexes_head:
            values.append(len(head_of(key).encode()))
        for var in self.filter_columns:
            kind = self.kind_of(var)
            values.append(ids[term_text(row[var])] if _named(row, var) else None if kind == "iri" else
                          filter_value(row.get(var), kind))  # fmt: skip
        values += [ids[term_text(row[var])] if var in row else None for var in self.own_anchors]
        if plan.is_aggregate:  # a count of the rows' keys counts their numbers
            kept = [plan.aggregates[column] for column in self.argument_columns]
            values += [unit if aggregate.argument == f"?{self.unit}" and aggregate.function == "count" else
                       _aggregate_input(aggregate.function, row.get(aggregate.argument[1:]))
                       for aggregate in kept]  # fmt: skip
        return tuple(values)

    @property
    def order(self) -> list[str]:
        """The variables of the sort key."""
        return self.plan.group_by if self.plan.is_aggregate else self.plan.order

    def key_iris(self, row: Row) -> list[str]:
        """The IRIs the row's sort key spells."""
        return [term.value for name in self.order if isinstance(term := row.get(name[1:]), NamedNode)]

    def stored_columns(self) -> list[str]:
        """The columns a stored row holds the values of, in their order."""
        return self.plan.group_by if self.plan.is_aggregate else self.plan.columns

    def loaded(self, text: str) -> dict[str, JsonValue]:
        """A row's text (`RowCodec.decode`) as a report's row."""
        return dict(zip((name[1:] for name in self.stored_columns()), _loaded(text), strict=True))


# A row's head, as a plain report's indexes hold it: the table stores only its length, the index its bytes, cut by
# SQLite from the sort key's (as bytes: SQLite's text functions stop at a key's first SEPARATOR; byte order is
# the keys' order). Queries name it as the index does.
HEAD = "substr(CAST(ord AS BLOB), 1, head_length)"


def head_of(key: str) -> str:
    """A sort key's head: its values up to the first that is not an IRI (a time, a number, a text). The IRIs
    before it are the hubs a report groups by (a robot, a person), few and shared by thousands of rows; the
    value after them tells rows apart, so heads rarely tie (a message's time, where its whole key also holds
    the IRIs that break ties: 11 bytes against about 60 in the timeline of messages).

    Heads sort as their keys do, ties aside. A value holds no SEPARATOR, and whether a head goes on past a
    value depends on that value alone: where two heads differ, their keys differ at the same place; a head
    cannot be a proper prefix of another unless its key ends there."""
    parts = key.split(SEPARATOR)
    end = next((index for index, part in enumerate(parts) if part[:1] not in ("1", "2")), len(parts) - 1)
    return SEPARATOR.join(parts[: end + 1])


@dataclass(frozen=True)
class Conditions:
    """A page's WHERE conditions and their arguments."""

    where: list[str]
    arguments: list[object]


def _named(row: Row, variable: str) -> bool:
    return isinstance(row.get(variable), NamedNode)


TERMS = "report_term_numbers"  # units and the IRIs filters compare, as numbers (views/terms.py, by digest)
# the database's own, beside each report's tables
OWN_TABLES = ("report_state", "report_changes", *terms.tables(TERMS, texts=False), DICTIONARIES, KEY_NAMESPACES)


class KeptRows:
    """Every materialised report's rows in one SQLite database (a file in the data directory, or temporary)."""

    def __init__(self, path: Path | None) -> None:
        self.changed = ChangeSignal()  # wakes this process's live readers once new changes are committed
        self.db = ViewDatabase(
            path,
            [
                "CREATE TABLE IF NOT EXISTS report_state (report TEXT PRIMARY KEY, fingerprint TEXT, through INTEGER)",
                "CREATE TABLE IF NOT EXISTS report_changes (seq INTEGER PRIMARY KEY AUTOINCREMENT, report TEXT, "
                "unit TEXT, through INTEGER)",
                *terms.schema(TERMS, texts=False),
                *row_codec.schema(),
                *key_namespaces.schema(),
            ],
        )
        self.terms = TermIds(TERMS, texts=False)
        self.codec = RowCodec()
        self.namespaces = KeyNamespaces()
        self.db.on_rollback(self._forget_made)

    # --- state ---------------------------------------------------------------------------------------

    def state(self, report: str) -> tuple[str | None, int]:
        row = (
            self.db.reader()
            .execute("SELECT fingerprint, through FROM report_state WHERE report = ?", (report,))
            .fetchone()
        )
        return (row[0], row[1]) if row else (None, 0)

    def set_state(self, report: str, fingerprint: str, through: int) -> None:
        with self.db.writing() as connection:
            connection.execute(
                "INSERT INTO report_state VALUES (?, ?, ?) ON CONFLICT (report) DO UPDATE SET "
                "fingerprint = excluded.fingerprint, through = excluded.through",
                (report, fingerprint, through),
            )

    def drop_unkept(self, tables: Collection[str], reports: Collection[str]) -> list[str]:
        """Drop every report table but `tables`, and the state of every report but `reports`: those of reports
        removed from the catalog, or become presets of another (their space is reused). Returns the tables
        dropped."""
        with self.db.writing() as connection:
            kept = {*tables, *OWN_TABLES}
            stored = [row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
            dropped = [name for name in stored if name.startswith("report_") and name not in kept]
            for name in dropped:
                connection.execute(f'DROP TABLE "{name}"')
            self.codec.keep_only(connection, kept)
            self.namespaces.keep_only(connection, kept)
            marks = ", ".join("?" * len(reports))
            connection.execute(f"DELETE FROM report_state WHERE report NOT IN ({marks})", list(reports))
        return dropped

    # --- writing -------------------------------------------------------------------------------------

    def create(self, layout: Layout, *, fresh: bool) -> None:
        with self.db.writing() as connection:
            if fresh:  # a facet's pairs are the graph's, whichever report keeps them: the build adds the missing
                for table in layout.own_tables:
                    connection.execute(f"DROP TABLE IF EXISTS {table}")
                self.codec.forget(connection, layout.own_tables)
                self.namespaces.forget(connection, layout.own_tables)
            for statement in layout.schema():
                connection.execute(statement)

    def replace(
        self, layout: Layout, units: Iterable[str], rows: dict[str, list[Row]], through: int, *, announce: bool = True
    ) -> None:
        """The rows of `units` are now `rows[unit]` (none for a unit that has no rows any more); `announce`: the
        change goes to the live streams (a build's rows are not a change a reader could follow)."""
        units = list(units)
        placeholders = ", ".join(["?"] * layout.column_count)
        with self.db.writing() as connection:
            texts = [text for unit in units for row in rows.get(unit, []) for text in layout.texts(row)]
            ids = self.terms.ids(connection, [*units, *texts])
            unit_ids = [ids[unit] for unit in units]
            record_units = [unit for unit in units for _ in rows.get(unit, [])]
            namespaces = self._namespaces(connection, layout, [row for unit in units for row in rows.get(unit, [])])
            records = [layout.record(ids[unit], index, row, ids, namespaces)
                       for unit in units for index, row in enumerate(rows.get(unit, []))]  # fmt: skip
            stored = self.codec.encode(connection, layout.table, [str(record[3]) for record in records])
            records = [(*record[:3], row, *record[4:]) for record, row in zip(records, stored, strict=True)]
            # (group, unit): the groups units join, and (below) those they were in
            joined = {(str(record[2]), ids[unit]) for unit, record in zip(record_units, records, strict=True)}
            left: set[tuple[str, int]] = set()
            for chunk in _chunks(unit_ids):
                marks = ", ".join(["?"] * len(chunk))
                if layout.plan.is_aggregate:
                    left.update(
                        connection.execute(f"SELECT ord, unit FROM {layout.table} WHERE unit IN ({marks})", chunk)
                    )
                connection.execute(f"DELETE FROM {layout.table} WHERE unit IN ({marks})", chunk)
            connection.executemany(f"INSERT INTO {layout.table} VALUES ({placeholders})", records)
            if layout.plan.is_aggregate:
                _regroup(connection, layout, left, joined)
            if announce:
                connection.executemany(
                    "INSERT INTO report_changes (report, unit, through) VALUES (?, ?, ?)",
                    [(layout.plan.name, unit, through) for unit in units],
                )

    def _namespaces(self, connection: Any, layout: Layout, rows: list[Row]) -> Namespaces:
        """The namespaces the table's keys are written with: made from its first rows (none yet: none needed)."""
        if not rows:
            return Namespaces()
        iris = (iri for row in rows for iri in layout.key_iris(row))
        return self.namespaces.for_writing(connection, layout.table, iris)

    def add_facets(self, layout: Layout, parameter: str, pairs: list[tuple[str, str]]) -> None:
        """A facet's pairs only grow as triples arrive (a clearing empties them with the rest)."""
        with self.db.writing() as connection:
            ids = self.terms.ids(connection, [text for pair in pairs for text in pair])
            connection.executemany(
                f"INSERT OR IGNORE INTO {layout.facet_tables[parameter]} VALUES (?, ?)",
                [(ids[value], ids[anchor]) for anchor, value in pairs],
            )

    def clear(self, layout: Layout) -> None:
        """The graph was emptied: the report's rows and its facets' pairs go (every report sharing them is
        cleared in the same step)."""
        with self.db.writing() as connection:
            for table in layout.tables:
                connection.execute(f"DELETE FROM {table}")
            self.codec.forget(connection, layout.own_tables)
            self.namespaces.forget(connection, layout.own_tables)
        # The terms stay (other reports' rows refer to them): a few numbers for IRIs no row holds any more.

    def _forget_made(self) -> None:
        """A write transaction rolled back: the numbers, dictionaries and namespaces made in it went with it."""
        self.terms.forget()
        self.codec.forget_made()
        self.namespaces.forget_made()

    def forget_erased(self) -> None:
        """An erasure: every report of these rows is cleared and built again; the table of terms and the change
        log go first (they would go on naming what was erased), and the writer forgets the ids it remembered."""
        with self.db.writing() as connection:
            connection.execute(f"DELETE FROM {TERMS}")
            connection.execute("DELETE FROM report_changes")
            for (facets,) in connection.execute(
                f"SELECT name FROM sqlite_master WHERE type = 'table' AND name LIKE '{FACETS_PREFIX}%'"
            ).fetchall():  # the pairs name what was erased; every report adds its facets' pairs again
                connection.execute(f'DELETE FROM "{facets}"')
            self.codec.forget(connection)
            self.namespaces.forget(connection)
        self.terms.forget()

    def prune_changes(self, keep: int) -> None:
        with self.db.writing() as connection:
            connection.execute(
                "DELETE FROM report_changes WHERE seq <= (SELECT MAX(seq) FROM report_changes) - ?", (keep,)
            )

    # --- reading -------------------------------------------------------------------------------------

    def page(self, layout: Layout, bound: dict[str, Any], limit: int, offset: int, after: str | None) -> Page:
        """Rows matching the bound parameters (name → term, None = not given), in the report's order."""
        # the rows, the dictionaries they were compressed with and the namespaces of their keys, as one version
        with self.db.snapshot():
            return self._page(layout, bound, limit, offset, after)

    def _page(self, layout: Layout, bound: dict[str, Any], limit: int, offset: int, after: str | None) -> Page:
        conditions = self._conditions(layout, bound)
        if conditions is None:  # a filter on an IRI no row holds
            return Page([], False, None)
        where, arguments = conditions.where, conditions.arguments
        if layout.plan.is_aggregate:
            return self._aggregate_page(layout, where, arguments, limit, offset, after)
        offset = 0 if after is not None else offset
        if after is not None:
            cursor = _cursor(after)
            where.append("(ord, unit, n) > (?, ?, ?)")
            where.append(f"{HEAD} >= ?")  # what the index can skip by itself
            arguments += [*cursor, head_of(str(cursor[0])).encode()]
        rows = self._head_page(layout, where, arguments, limit, offset)
        kept = rows[:limit]
        last = _cursor_of(kept[-1][0], kept[-1][1], kept[-1][2]) if kept else None
        loaded = [layout.loaded(self._text(row[3])) for row in kept]
        return Page(loaded, len(rows) > limit, last if len(rows) > limit else None)

    def _head_page(
        self, layout: Layout, where: list[str], arguments: list[object], limit: int, offset: int
    ) -> list[Any]:
        """The first `offset + limit + 1` rows the conditions match, in the report's order, skipping `offset`.
        They are chosen by their heads from an index that holds them: the order's, or a filter's (a window
        matches thousands of rows in another order than the report's, and only the page's rows are read: a
        page of a one-day window at 1M triples, 23 ms with every matching row sorted whole, 11 ms so). The
        rows whose head is at most the last head chosen hold the page whole — a row of a greater head sorts
        after them all — and are put in the whole key's order."""
        reader = self.db.reader()
        wanted = offset + limit + 1
        clause = f"WHERE {' AND '.join(where)}" if where else ""
        heads = reader.execute(
            f"SELECT {HEAD} FROM {layout.table} {clause} ORDER BY {HEAD}, unit, n LIMIT ?", [*arguments, wanted]
        ).fetchall()
        if len(heads) == wanted:
            clause += f" {'AND' if where else 'WHERE'} {HEAD} <= ?"
            arguments = [*arguments, heads[-1][0]]
        chosen = f"SELECT rowid FROM {layout.table} {clause}"
        return reader.execute(
            f"SELECT ord, unit, n, row FROM {layout.table} WHERE rowid IN ({chosen}) ORDER BY ord, unit, n "
            "LIMIT ? OFFSET ?",
            [*arguments, limit + 1, offset],
        ).fetchall()

    def changes_since(self, seq: int, limit: int = 1000) -> list[tuple[int, str, str]]:
        """(seq, report, unit) of the changes after `seq`, oldest first."""
        return (
            self.db.reader()
            .execute("SELECT seq, report, unit FROM report_changes WHERE seq > ? ORDER BY seq LIMIT ?", (seq, limit))
            .fetchall()
        )

    def oldest_change(self) -> int:
        return self.db.reader().execute("SELECT COALESCE(MIN(seq), 0) FROM report_changes").fetchone()[0]

    def last_change(self) -> int:
        return self.db.reader().execute("SELECT COALESCE(MAX(seq), 0) FROM report_changes").fetchone()[0]

    def count(self, layout: Layout, bound: dict[str, Any]) -> int:
        """How many rows match the bound parameters (plain queries: an aggregate's rows are its groups)."""
        with self.db.snapshot() as reader:  # the rows and the namespaces their keys were written with
            conditions = self._conditions(layout, bound)
            if conditions is None:  # a filter on an IRI no row holds
                return 0
            where, arguments = conditions.where, conditions.arguments
            clause = f"WHERE {' AND '.join(where)}" if where else ""
            return int(reader.execute(f"SELECT COUNT(*) FROM {layout.table} {clause}", arguments).fetchone()[0])

    def rows_of(self, layout: Layout, iris: Sequence[str]) -> list[dict[str, JsonValue]]:
        """The rows whose key is one of these IRIs, in the query's order."""
        with self.db.snapshot() as reader:
            wanted = [term_text(NamedNode(iri)) for iri in iris]
            ids = list(terms.lookup(reader, TERMS, wanted, texts=False).values())
            found: list[tuple[str, int, int, str | bytes]] = []
            for chunk in _chunks(ids):
                marks = ", ".join("?" * len(chunk))
                found += reader.execute(f"SELECT ord, unit, n, row FROM {layout.table} WHERE unit IN ({marks})", chunk)
            return [layout.loaded(self._text(row[3])) for row in sorted(found, key=lambda row: row[:3])]

    def _text(self, stored: str | bytes) -> str:
        """A stored row's text, inside a snapshot (its dictionary is read in the same version as the row)."""
        return self.codec.decode(self.db.reader(), stored)

    def _conditions(self, layout: Layout, bound: dict[str, Any]) -> Conditions | None:
        """The WHERE conditions of the bound parameters; None when one names an IRI no row holds."""
        where: list[str] = []
        arguments: list[object] = []
        named = [term_text(term) for name, term in bound.items() if isinstance(term, NamedNode)]
        ids = terms.lookup(self.db.reader(), TERMS, named, texts=False) if named else {}
        for condition in layout.plan.column_filters:
            term = bound.get(condition.parameter)
            if term is None:
                continue
            column = condition.column[1:]
            if column == layout.sorted_by:  # the rows of one value are a range of the sort key, and of its head
                prefix = sort_key([term], self.namespaces.for_reading(self.db.reader(), layout.table)) + SEPARATOR
                bounds = [prefix, prefix[:-1] + chr(ord(SEPARATOR) + 1)]
                order = layout.order_column
                where.append(f"{order} >= ? AND {order} < ?")
                arguments += [edge.encode() for edge in bounds] if layout.indexes_head else bounds
                continue
            kind = layout.parameters[condition.parameter].type
            if kind == "iri":
                if term_text(term) not in ids:
                    return None
                value: object = ids[term_text(term)]
            else:
                value = filter_value(term, kind)
            where.append(f"{layout.filter_columns[column]} {condition.op} ?")
            arguments.append(value)
        for facet in layout.plan.facet_filters:
            term = bound.get(facet.parameter)
            if term is None:
                continue
            if term_text(term) not in ids:
                return None
            anchor = layout.anchors[facet.anchor[1:]]
            where.append(f"{anchor} IN (SELECT anchor FROM {layout.facet_tables[facet.parameter]} WHERE value = ?)")
            arguments.append(ids[term_text(term)])
        return Conditions(where, arguments)

    def _aggregate_page(
        self, layout: Layout, where: list[str], arguments: list[object], limit: int, offset: int, after: str | None
    ) -> Page:
        """Unfiltered, a page of the kept groups; filtered, the matching contributions grouped as they are read."""
        if where:
            clause = f"WHERE {' AND '.join(where)}"
            having = "HAVING ord > ?" if after is not None else ""
            text = f"SELECT {layout.grouped()} FROM {layout.table} {clause} GROUP BY ord {having} ORDER BY ord"
        else:
            values = ", ".join(f"v_{i}" for i in range(len(layout.plan.aggregates)))
            clause = "WHERE ord > ?" if after is not None else ""
            text = f"SELECT ord, row, {values} FROM {layout.table}_groups {clause} ORDER BY ord"
        rows = (
            self.db.reader()
            .execute(
                f"{text} LIMIT ? OFFSET ?",
                [*arguments, *([after] if after is not None else []), limit + 1, 0 if after is not None else offset],
            )
            .fetchall()
        )
        kept = rows[:limit]
        out = []
        for row in kept:
            groups = layout.loaded(self._text(row[1]))
            for aggregate, value in zip(layout.plan.aggregates, row[2:], strict=True):
                groups[aggregate.output[1:]] = _aggregate_output(aggregate.function, value)
            out.append(groups)
        has_more = len(rows) > limit
        return Page(out, has_more, kept[-1][0] if has_more and kept else None)

    def close(self) -> None:
        self.db.close()


def _regroup(connection: Any, layout: Layout, left: set[tuple[str, int]], joined: set[tuple[str, int]]) -> None:
    """Bring the kept aggregates of the groups units `left` and `joined` ((group, unit) pairs) up to their
    contributions, in what these touch rather than in every contribution of a group: a group that grows
    without end (a robot and the one person it meets every day) costs a post the same at its first
    contribution and its millionth. The count of distinct units moves by the units that joined or left;
    a minimum, maximum or sample is read from the group's index on its argument; a group's row (its group
    columns) is any of its contributions'. A group left without contributions goes."""
    plan = layout.plan
    moved: dict[str, int] = {}
    for group, _ in joined - left:
        moved[group] = moved.get(group, 0) + 1
    for group, _ in left - joined:
        moved[group] = moved.get(group, 0) - 1
    # The count of distinct units (what the report counts its contributions by) moves; others are read.
    counted = next(i for i, a in enumerate(plan.aggregates) if a.function == "count" and a.distinct)
    table, groups = layout.table, f"{layout.table}_groups"
    values = ", ".join(f"v_{i}" for i in range(len(plan.aggregates)))
    for group in sorted({group for group, _ in left | joined}):
        sample = connection.execute(f"SELECT row FROM {table} WHERE ord = ? LIMIT 1", (group,)).fetchone()
        if sample is None:
            connection.execute(f"DELETE FROM {groups} WHERE ord = ?", (group,))
            continue
        kept = connection.execute(f"SELECT v_{counted} FROM {groups} WHERE ord = ?", (group,)).fetchone()
        aggregates: list[object] = []
        for index, aggregate in enumerate(plan.aggregates):
            if index == counted:
                aggregates.append((int(kept[0]) if kept else 0) + moved.get(group, 0))
                continue
            # MIN serves SAMPLE (any value will do), from the group's index on the argument like MIN and MAX
            function = _sql_aggregate(aggregate.function, aggregate.distinct, f"g_{layout.argument_column[index]}")
            found = connection.execute(f"SELECT {function} FROM {table} WHERE ord = ?", (group,)).fetchone()
            aggregates.append(found[0])
        marks = ", ".join("?" * (2 + len(aggregates)))
        connection.execute(f"INSERT OR REPLACE INTO {groups} (ord, row, {values}) VALUES ({marks})",
                           [group, sample[0], *aggregates])  # fmt: skip


def _chunks(items: Sequence[Any], size: int = 500) -> Iterable[Sequence[Any]]:
    for start in range(0, len(items), size):
        yield items[start : start + size]


def _stored(term: Term | None) -> JsonValue:
    return json_value(term)


def _aggregate_input(function: str, term: Term | None) -> str | None:
    if term is None:
        return None
    if function == "count":
        return term_text(term)
    if function == "sample":
        return json.dumps(json_value(term))
    return sort_key([term])


def _sql_aggregate(function: str, distinct: bool, column: str) -> str:
    if function == "count":
        return f"COUNT({'DISTINCT ' if distinct else ''}{column})"
    return f"{'MAX' if function == 'max' else 'MIN'}({column})"  # MIN serves SAMPLE: any value will do


JSON_MARK = " "  # begins a row orjson cannot write (an integer past 64 bits): json wrote it, json reads it


def _row_text(row: list[JsonValue]) -> str:
    """A row as stored: orjson's JSON (NaN and infinities, which JSON cannot hold, become null, as in every
    answer); json's, marked, for a row holding an integer past 64 bits, which orjson neither writes nor reads
    back exactly."""
    try:
        return orjson.dumps(row).decode()
    except TypeError:
        return JSON_MARK + json.dumps(row)


def _loaded(text: str) -> list[JsonValue]:
    """A stored row, read by whoever wrote it: orjson reads a page of rows several times faster than json
    (1,000 rows: 1.4 ms against 4.7 ms)."""
    row: list[JsonValue] = json.loads(text) if text.startswith(JSON_MARK) else orjson.loads(text)
    return row


def _aggregate_output(function: str, value: object) -> JsonValue:
    if value is None:
        return None
    if function == "count":
        return int(value)  # type: ignore[call-overload]
    if function == "sample":
        loaded: JsonValue = json.loads(str(value))
        return loaded
    return _decoded(str(value))


def _decoded(key: str) -> JsonValue:
    """The JSON value a one-term sort key stands for (the inverse of encoding._sort_part)."""
    kind, text = key[0], key[1:]
    if kind == "2":
        return text
    if kind == "3":
        bits = int(text, 16)
        bits = bits ^ (1 << 63) if bits >> 63 else bits ^ 0xFFFFFFFFFFFFFFFF
        return struct.unpack(">d", struct.pack(">Q", bits))[0]
    if kind == "4":
        return iso_time(instant_of_part(text))
    return text


def _cursor(after: str) -> list[object]:
    """The position a `next` cursor names. Cursors come back from clients: anything but one this server
    made is refused by name."""
    try:
        decoded = json.loads(base64.urlsafe_b64decode(after.encode("ascii") + b"=" * (-len(after) % 4)))
    except (ValueError, UnicodeError):  # binascii.Error and JSONDecodeError are ValueErrors
        decoded = None
    if not (
        isinstance(decoded, list)
        and len(decoded) == 3
        and isinstance(decoded[0], str)
        and isinstance(decoded[1], int)
        and 0 <= decoded[1] < 2**63  # a unit's number, within SQLite's integers
        and isinstance(decoded[2], int)
        and 0 <= decoded[2] < 2**63  # a row's index, within SQLite's integers
    ):
        raise InvalidParameter("after", "not a cursor this server made: pass the `next` of the previous page")
    return decoded


def _cursor_of(order: str, unit: str, index: int) -> str:
    """Opaque and URL-safe: clients pass it back as it is."""
    return base64.urlsafe_b64encode(json.dumps([order, unit, index]).encode()).decode("ascii").rstrip("=")
