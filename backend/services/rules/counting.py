"""How many rows of a kept query match its filters, counted in its own SQLite table (for the rules' counts).

Kept apart from `upkeep/kept_queries/rows.py`, which pages rows but does not count them: it reads the table
through the same conditions a page is chosen by (`KeptRows._conditions`), so a count and its pages never
disagree on what a filter keeps.
"""

from __future__ import annotations

from typing import Any

from segb_server.backend.services.upkeep.kept_queries.rows import KeptRows, Layout


def count_rows(rows: KeptRows, layout: Layout, bound: dict[str, Any]) -> int:
    """Rows of `layout` matching the bound parameters (name → term, None = not given). Plain reports only."""
    where, arguments = rows._conditions(layout, bound)
    clause = f"WHERE {' AND '.join(where)}" if where else ""
    return int(rows.db.reader().execute(f"SELECT COUNT(*) FROM {layout.table} {clause}", arguments).fetchone()[0])
