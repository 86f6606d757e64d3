"""Reading a kept query's own table beyond its pages: how many rows match its filters, and the rows of given keys
(the rules' counts, and the findings about the nodes a page shows).

Kept apart from `upkeep/kept_queries/rows.py`, which pages rows but neither counts them nor reads them by key: it
goes through the same conditions a page is chosen by (`KeptRows._conditions`) and the same table of terms the
keys are stored as, so a count, its pages and the rows read by key never disagree.
"""

from __future__ import annotations

from typing import Any

from pyoxigraph import NamedNode

from segb_server.backend.services.upkeep import terms
from segb_server.backend.services.upkeep.kept_queries.rows import TERMS, KeptRows, Layout
from segb_server.backend.services.values import JsonValue
from segb_server.backend.store.terms import term_text

CHUNK = 500


def count_rows(rows: KeptRows, layout: Layout, bound: dict[str, Any]) -> int:
    """Rows of `layout` matching the bound parameters (name → term, None = not given). Plain queries only."""
    conditions = rows._conditions(layout, bound)
    if conditions is None:  # a filter on an IRI no row holds
        return 0
    where, arguments = conditions
    clause = f"WHERE {' AND '.join(where)}" if where else ""
    return int(rows.db.reader().execute(f"SELECT COUNT(*) FROM {layout.table} {clause}", arguments).fetchone()[0])


def rows_about(rows: KeptRows, layout: Layout, iris: list[str]) -> list[dict[str, JsonValue]]:
    """The rows whose key is one of these IRIs, in the query's order."""
    reader = rows.db.reader()
    ids = list(terms.lookup(reader, TERMS, [term_text(NamedNode(iri)) for iri in iris]).values())
    found: list[tuple[str, int, int, str]] = []
    for start in range(0, len(ids), CHUNK):
        chunk = ids[start : start + CHUNK]
        marks = ", ".join("?" * len(chunk))
        found += reader.execute(
            f"SELECT ord, unit, n, row FROM {layout.table} WHERE unit IN ({marks})", chunk
        ).fetchall()
    return [layout.loaded(row[3]) for row in sorted(found)]
