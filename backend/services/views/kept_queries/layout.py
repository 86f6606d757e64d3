"""How one report's rows are stored (`Layout`): its table, the columns its filters compare and their indexes, and
each row as a record of them; and a sort key's head (`head_of`), what a plain report's indexes hold."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import orjson
from pyoxigraph import NamedNode

from segb_server.backend.services.sparql.catalog import Parameter
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.services.views.kept_queries.aggregate_values import aggregate_input, sql_aggregate
from segb_server.backend.services.views.kept_queries.encoding import SEPARATOR, filter_value, sort_key
from segb_server.backend.services.views.kept_queries.key_namespaces import Namespaces
from segb_server.backend.services.views.kept_queries.plan import ReportPlan
from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text

Row = dict[str, Term]  # one solution: variable name (without ?) → term


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
            # The sort key (or its head): a filtered page is chosen from this index alone (`pages.py`).
            statements.append(
                f"CREATE INDEX IF NOT EXISTS {self.table}_{sql} ON {self.table} ({sql}, {self.order_column}, unit, n)"
            )
        if self.plan.is_aggregate:
            for index, kept in enumerate(self.plan.aggregates):
                # a group's extreme is read from its index (`rows.py`, `_regroup`), one index a column
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
        aggregates = ", ".join(sql_aggregate(aggregate.function, aggregate.distinct, f"g_{column}")
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
                       aggregate_input(aggregate.function, row.get(aggregate.argument[1:]))
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


def _named(row: Row, variable: str) -> bool:
    return isinstance(row.get(variable), NamedNode)


def _stored(term: Term | None) -> JsonValue:
    return json_value(term)


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
