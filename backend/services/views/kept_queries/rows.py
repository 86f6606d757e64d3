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
each index); a page is chosen by its heads and its rows then put in the whole key's order (`pages.py`).
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from pathlib import Path
from typing import Any

from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.kept_queries.aggregate_values import sql_aggregate
from segb_server.backend.services.views.kept_queries.facets import FACETS_PREFIX
from segb_server.backend.services.views.kept_queries.key_namespaces import KeyNamespaces, Namespaces
from segb_server.backend.services.views.kept_queries.layout import Layout, Row
from segb_server.backend.services.views.kept_queries.pages import RowReader
from segb_server.backend.services.views.kept_queries.row_codec import RowCodec
from segb_server.backend.services.views.kept_queries.rows_database import OWN_TABLES, SCHEMA, TERMS, chunks
from segb_server.backend.services.views.signal import ChangeSignal
from segb_server.backend.services.views.terms import TermIds


class KeptRows(RowReader):
    """Every materialised report's rows in one SQLite database (a file in the data directory, or temporary):
    written here, read as `RowReader` reads them."""

    def __init__(self, path: Path | None) -> None:
        self.changed = ChangeSignal()  # wakes this process's live readers once new changes are committed
        super().__init__(ViewDatabase(path, SCHEMA), RowCodec(), KeyNamespaces())
        self.terms = TermIds(TERMS, texts=False)
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
            for chunk in chunks(unit_ids):
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
            function = sql_aggregate(aggregate.function, aggregate.distinct, f"g_{layout.argument_column[index]}")
            found = connection.execute(f"SELECT {function} FROM {table} WHERE ord = ?", (group,)).fetchone()
            aggregates.append(found[0])
        marks = ", ".join("?" * (2 + len(aggregates)))
        connection.execute(f"INSERT OR REPLACE INTO {groups} (ord, row, {values}) VALUES ({marks})",
                           [group, sample[0], *aggregates])  # fmt: skip
