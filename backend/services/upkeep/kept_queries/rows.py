"""The rows of materialised reports, in SQLite: replaced key by key as the graph changes, read page by page
with the report's filters as indexed comparisons and its order as an index (keyset paging).

A plain report keeps its rows as its query gives them. An aggregate report keeps its contributions (the rows
before grouping, one unit per value of its COUNT(DISTINCT …) argument), so filters that apply before grouping
(a time window) stay exact when a filtered page groups them as it is read. Its unfiltered pages, the ones every
visit opens with, read its groups: each group's aggregates kept in a table of their own, computed again for
the groups a replacement touches, so a first page costs its own rows however many contributions there are.
"""

from __future__ import annotations

import base64
import json
import struct
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import orjson
from pyoxigraph import NamedNode

from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.sparql.catalog import Parameter
from segb_server.backend.services.upkeep.database import ViewDatabase
from segb_server.backend.services.upkeep.kept_queries.encoding import filter_value, sort_key
from segb_server.backend.services.upkeep.kept_queries.plan import ReportPlan
from segb_server.backend.services.upkeep.signal import ChangeSignal
from segb_server.backend.services.values import JsonValue, iso_time, json_value
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

    @property
    def filter_columns(self) -> dict[str, str]:
        """Column variable (without ?) → SQL column, for each column a filter compares."""
        return {f.column[1:]: f"f_{f.column[1:]}" for f in self.plan.column_filters}

    @property
    def anchors(self) -> dict[str, str]:
        return {f.anchor[1:]: f"a_{f.anchor[1:]}" for f in self.plan.facet_filters}

    def kind_of(self, column: str) -> str:
        kinds = {f.column[1:]: self.parameters[f.parameter].type for f in self.plan.column_filters}
        return kinds[column]

    @property
    def column_count(self) -> int:
        aggregates = len(self.plan.aggregates) if self.plan.is_aggregate else 0
        return 4 + len(self.filter_columns) + len(self.anchors) + aggregates

    def schema(self) -> list[str]:
        filters = [f"{sql} {'REAL' if self.kind_of(var) in ('decimal', 'integer') else 'TEXT'}"
                   for var, sql in self.filter_columns.items()]  # fmt: skip
        anchors = [f"{sql} TEXT" for sql in self.anchors.values()]
        aggregate = [f"g_{i} TEXT" for i in range(len(self.plan.aggregates))] if self.plan.is_aggregate else []
        columns = ", ".join(["unit TEXT", "n INTEGER", "ord TEXT", "row TEXT", *filters, *anchors, *aggregate])
        statements = [
            f"CREATE TABLE IF NOT EXISTS {self.table} ({columns}, PRIMARY KEY (unit, n))",
            f"CREATE INDEX IF NOT EXISTS {self.table}_ord ON {self.table} (ord, unit, n)",
            f"CREATE TABLE IF NOT EXISTS {self.table}_facets (param TEXT, value TEXT, anchor TEXT, "
            "PRIMARY KEY (param, value, anchor))",
        ]
        for sql in [*self.filter_columns.values(), *self.anchors.values()]:
            # The whole sort key: a filtered page is sorted from this index alone (see `page`).
            statements.append(f"CREATE INDEX IF NOT EXISTS {self.table}_{sql} ON {self.table} ({sql}, ord, unit, n)")
        if self.plan.is_aggregate:
            for index, kept in enumerate(self.plan.aggregates):
                if kept.function != "count":  # a group's extreme is read from its index (`_regroup`)
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
    def tables(self) -> list[str]:
        return [self.table, f"{self.table}_facets", *([f"{self.table}_groups"] if self.plan.is_aggregate else [])]

    def grouped(self) -> str:
        """The SELECT list of a group: its order, its sample row, each aggregate over its contributions."""
        aggregates = ", ".join(_sql_aggregate(aggregate.function, aggregate.distinct, f"g_{index}")
                               for index, aggregate in enumerate(self.plan.aggregates))  # fmt: skip
        return f"ord, MIN(row), {aggregates}"

    def record(self, unit: str, index: int, row: Row) -> tuple[object, ...]:
        """One stored row: its unit, place, sort key, JSON, filter values, anchors, aggregate arguments."""
        plan = self.plan
        order = plan.group_by if plan.is_aggregate else plan.order
        values: list[object] = [unit, index, sort_key([row.get(name[1:]) for name in order])]
        values.append(_row_text({name[1:]: _stored(row.get(name[1:])) for name in self._stored_columns()}))
        values += [filter_value(row.get(var), self.kind_of(var)) for var in self.filter_columns]
        values += [term_text(row[var]) if var in row else None for var in self.anchors]
        if plan.is_aggregate:
            values += [_aggregate_input(aggregate.function, row.get(aggregate.argument[1:]))
                       for aggregate in plan.aggregates]  # fmt: skip
        return tuple(values)

    def _stored_columns(self) -> list[str]:
        return self.plan.group_by if self.plan.is_aggregate else self.plan.columns


OWN_TABLES = ("report_state", "report_changes")  # the database's own, beside each report's tables


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
            ],
        )

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
            marks = ", ".join("?" * len(reports))
            connection.execute(f"DELETE FROM report_state WHERE report NOT IN ({marks})", list(reports))
        return dropped

    # --- writing -------------------------------------------------------------------------------------

    def create(self, layout: Layout, *, fresh: bool) -> None:
        with self.db.writing() as connection:
            if fresh:
                for table in layout.tables:
                    connection.execute(f"DROP TABLE IF EXISTS {table}")
            for statement in layout.schema():
                connection.execute(statement)

    def replace(self, layout: Layout, units: Iterable[str], rows: dict[str, list[Row]], through: int) -> None:
        """The rows of `units` are now `rows[unit]` (none for a unit that has no rows any more)."""
        units = list(units)
        placeholders = ", ".join(["?"] * layout.column_count)
        records = [layout.record(unit, index, row) for unit in units for index, row in enumerate(rows.get(unit, []))]
        joined = {(str(record[2]), str(record[0])) for record in records}  # (group, unit): the groups units join
        left: set[tuple[str, str]] = set()  # and (below) those they were in
        with self.db.writing() as connection:
            for chunk in _chunks(units):
                marks = ", ".join(["?"] * len(chunk))
                if layout.plan.is_aggregate:
                    left.update(
                        connection.execute(f"SELECT ord, unit FROM {layout.table} WHERE unit IN ({marks})", chunk)
                    )
                connection.execute(f"DELETE FROM {layout.table} WHERE unit IN ({marks})", chunk)
            connection.executemany(f"INSERT INTO {layout.table} VALUES ({placeholders})", records)
            if layout.plan.is_aggregate:
                _regroup(connection, layout, left, joined)
            connection.executemany(
                "INSERT INTO report_changes (report, unit, through) VALUES (?, ?, ?)",
                [(layout.plan.name, unit, through) for unit in units],
            )

    def add_facets(self, layout: Layout, parameter: str, pairs: list[tuple[str, str]]) -> None:
        """A facet's pairs only grow as triples arrive (a clearing empties them with the rest)."""
        with self.db.writing() as connection:
            connection.executemany(
                f"INSERT OR IGNORE INTO {layout.table}_facets VALUES (?, ?, ?)",
                [(parameter, value, anchor) for anchor, value in pairs],
            )

    def clear(self, layout: Layout) -> None:
        with self.db.writing() as connection:
            for table in layout.tables:
                connection.execute(f"DELETE FROM {table}")

    def prune_changes(self, keep: int) -> None:
        with self.db.writing() as connection:
            connection.execute(
                "DELETE FROM report_changes WHERE seq <= (SELECT MAX(seq) FROM report_changes) - ?", (keep,)
            )

    # --- reading -------------------------------------------------------------------------------------

    def page(self, layout: Layout, bound: dict[str, Any], limit: int, offset: int, after: str | None) -> Page:
        """Rows matching the bound parameters (name → term, None = not given), in the report's order."""
        where, arguments = self._conditions(layout, bound)
        if layout.plan.is_aggregate:
            return self._aggregate_page(layout, where, arguments, limit, offset, after)
        if after is not None:
            where.append("(ord, unit, n) > (?, ?, ?)")
            arguments += _cursor(after)
        clause = f"WHERE {' AND '.join(where)}" if where else ""
        chosen = f"FROM {layout.table} {clause} ORDER BY ord, unit, n LIMIT ? OFFSET ?"
        if where:
            # A window (since/until) matches thousands of rows in another order than the report's: the page is
            # chosen from the filter's index, which holds the sort key, and only its rows are read (a page of a
            # one-day window at 1M triples: 23 ms with every matching row sorted whole, 11 ms so).
            chosen = f"FROM {layout.table} WHERE rowid IN (SELECT rowid {chosen}) ORDER BY ord, unit, n"
        rows = (
            self.db.reader()
            .execute(f"SELECT ord, unit, n, row {chosen}", [*arguments, limit + 1, 0 if after is not None else offset])
            .fetchall()
        )
        kept = rows[:limit]
        last = _cursor_of(kept[-1][0], kept[-1][1], kept[-1][2]) if kept else None
        return Page([_loaded(row[3]) for row in kept], len(rows) > limit, last if len(rows) > limit else None)

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

    def unit_rows(self, layout: Layout, units: Sequence[str]) -> list[dict[str, JsonValue]]:
        if not units:
            return []
        found = (
            self.db.reader()
            .execute(
                f"SELECT row FROM {layout.table} WHERE unit IN ({', '.join(['?'] * len(units))}) ORDER BY ord, unit, n",
                list(units),
            )
            .fetchall()
        )
        return [_loaded(row[0]) for row in found]

    def _conditions(self, layout: Layout, bound: dict[str, Any]) -> tuple[list[str], list[object]]:
        where: list[str] = []
        arguments: list[object] = []
        for condition in layout.plan.column_filters:
            term = bound.get(condition.parameter)
            if term is None:
                continue
            value = filter_value(term, layout.parameters[condition.parameter].type)
            where.append(f"f_{condition.column[1:]} {condition.op} ?")
            arguments.append(value)
        for facet in layout.plan.facet_filters:
            term = bound.get(facet.parameter)
            if term is None:
                continue
            where.append(
                f"a_{facet.anchor[1:]} IN (SELECT anchor FROM {layout.table}_facets WHERE param = ? AND value = ?)"
            )
            arguments += [facet.parameter, term_text(term)]
        return where, arguments

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
            groups = _loaded(row[1])
            for aggregate, value in zip(layout.plan.aggregates, row[2:], strict=True):
                groups[aggregate.output[1:]] = _aggregate_output(aggregate.function, value)
            out.append(groups)
        has_more = len(rows) > limit
        return Page(out, has_more, kept[-1][0] if has_more and kept else None)

    def close(self) -> None:
        self.db.close()


def _regroup(connection: Any, layout: Layout, left: set[tuple[str, str]], joined: set[tuple[str, str]]) -> None:
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
            function = _sql_aggregate(aggregate.function, aggregate.distinct, f"g_{index}")
            found = connection.execute(f"SELECT {function} FROM {table} WHERE ord = ?", (group,)).fetchone()
            aggregates.append(found[0])
        marks = ", ".join("?" * (2 + len(aggregates)))
        connection.execute(f"INSERT OR REPLACE INTO {groups} (ord, row, {values}) VALUES ({marks})",
                           [group, sample[0], *aggregates])  # fmt: skip


def _chunks(items: Sequence[str], size: int = 500) -> Iterable[Sequence[str]]:
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


def _row_text(row: dict[str, JsonValue]) -> str:
    """A row as stored: orjson's JSON (NaN and infinities, which JSON cannot hold, become null, as in every
    answer); json's, marked, for a row holding an integer past 64 bits, which orjson neither writes nor reads
    back exactly."""
    try:
        return orjson.dumps(row).decode()
    except TypeError:
        return JSON_MARK + json.dumps(row)


def _loaded(text: str) -> dict[str, JsonValue]:
    """A stored row, read by whoever wrote it: orjson reads a page of rows several times faster than json
    (1,000 rows: 1.4 ms against 4.7 ms)."""
    row: dict[str, JsonValue] = json.loads(text) if text.startswith(JSON_MARK) else orjson.loads(text)
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
        return iso_time(text + "+00:00")
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
        and isinstance(decoded[1], str)
        and isinstance(decoded[2], int)
        and 0 <= decoded[2] < 2**63  # a row's index, within SQLite's integers
    ):
        raise InvalidParameter("after", "not a cursor this server made: pass the `next` of the previous page")
    return decoded


def _cursor_of(order: str, unit: str, index: int) -> str:
    """Opaque and URL-safe: clients pass it back as it is."""
    return base64.urlsafe_b64encode(json.dumps([order, unit, index]).encode()).decode("ascii").rstrip("=")


def unit_of(values: Sequence[Term]) -> str:
    """A key (one term or several) as the text rows are stored under."""
    return " ".join(term_text(value) for value in values)


def iri_unit(iri: str) -> str:
    return term_text(NamedNode(iri))
