"""Whether a step changed what the graph's first view draws (the view every visit opens with, kept until it does):
the nodes it wrote, before and after, against the last row the view reads, and the links it added."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable
from time import time_ns
from typing import Any

from pyoxigraph import NamedNode, Quad

from segb_server.backend.services.graph.candidates import FIRST_VIEW
from segb_server.backend.services.graph.facts import chunks

# The first view's nodes are the first rows of graph_nodes in this order (`CandidateQuery` with no filter).
_FIRST_VIEW_ORDER = "ORDER BY rank, instant, tie, id"
_ROW_COLUMNS = "id, rank, instant, tie, time, label, typeset"  # the sort key follows the id


def first_view_cutoff(connection: sqlite3.Connection) -> tuple[Any, ...] | None:
    """The sort key of the last row the first view reads (its limit and one more, which tells whether it is cut
    off); None while there are fewer nodes, when every node is in it."""
    return connection.execute(
        f"SELECT rank, instant, tie, id FROM graph_nodes {_FIRST_VIEW_ORDER} LIMIT 1 OFFSET ?", (FIRST_VIEW.limit,)
    ).fetchone()


def node_rows(connection: sqlite3.Connection, nodes: Iterable[int]) -> dict[int, tuple[Any, ...]]:
    rows: dict[int, tuple[Any, ...]] = {}
    for chunk in chunks(sorted(nodes)):
        marks = ", ".join("?" * len(chunk))
        for row in connection.execute(f"SELECT {_ROW_COLUMNS} FROM graph_nodes WHERE id IN ({marks})", chunk):
            rows[row[0]] = row
    return rows


def first_view_changed(
    cutoff: tuple[Any, ...] | None,
    before: dict[int, tuple[Any, ...]],
    after: dict[int, tuple[Any, ...]],
    links: list[tuple[int, int]],
) -> bool:
    """Whether the first view draws something else now that the nodes in `after` (every node written) were
    `before` (absent: new) and `links` were added. Only a node written inside the view's rows, before or after,
    changes them; when none did, the view's rows are those up to `cutoff` as before, and a new link changes it
    when both its ends are among them."""

    def drawn(row: tuple[Any, ...] | None) -> bool:
        return row is not None and (cutoff is None or (row[1], row[2], row[3], row[0]) <= cutoff)

    for node, row in after.items():
        old = before.get(node)
        if row != old and (drawn(old) or drawn(row)):
            return True
    return any(drawn(after.get(source)) and drawn(after.get(target)) for source, target in links)


def subjects_and_targets(quads: Iterable[Quad]) -> set[str]:
    """The IRIs the facts may add as nodes: named subjects and named objects."""
    return {term.value for quad in quads for term in (quad.subject, quad.object) if isinstance(term, NamedNode)}


def new_first_view(connection: sqlite3.Connection) -> None:
    """A first view unlike any kept one (after a build or a clearing, which start the counter again)."""
    connection.execute("UPDATE graph_state SET first_view = ?", (time_ns(),))
