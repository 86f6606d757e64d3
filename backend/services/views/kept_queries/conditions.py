"""The WHERE conditions a page's bound parameters become: a comparison on a filter's column, a range of the sort
key for the first column the report sorts by, a facet's anchors among its pairs."""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from typing import Any

from pyoxigraph import NamedNode

from segb_server.backend.services.views import terms
from segb_server.backend.services.views.kept_queries.encoding import SEPARATOR, filter_value, sort_key
from segb_server.backend.services.views.kept_queries.key_namespaces import KeyNamespaces
from segb_server.backend.services.views.kept_queries.layout import Layout
from segb_server.backend.services.views.kept_queries.rows_database import TERMS
from segb_server.backend.store.terms import term_text


@dataclass(frozen=True)
class Conditions:
    """A page's WHERE conditions and their arguments."""

    where: list[str]
    arguments: list[object]


def page_conditions(
    reader: sqlite3.Connection, namespaces: KeyNamespaces, layout: Layout, bound: dict[str, Any]
) -> Conditions | None:
    """The WHERE conditions of the bound parameters; None when one names an IRI no row holds. `reader`: the
    connection the page is read on (the namespaces of the sort key are those its rows were written with)."""
    where: list[str] = []
    arguments: list[object] = []
    named = [term_text(term) for name, term in bound.items() if isinstance(term, NamedNode)]
    ids = terms.lookup(reader, TERMS, named, texts=False) if named else {}
    for condition in layout.plan.column_filters:
        term = bound.get(condition.parameter)
        if term is None:
            continue
        column = condition.column[1:]
        if column == layout.sorted_by:  # the rows of one value are a range of the sort key, and of its head
            prefix = sort_key([term], namespaces.for_reading(reader, layout.table)) + SEPARATOR
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
