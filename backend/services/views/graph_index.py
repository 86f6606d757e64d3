"""The drawable graph kept as indexed rows, current with each applied journal step (a `KeptView`).

The facts (links, types, the literals it keeps) are stored as they arrive, every IRI as a number (`views/terms.py`);
each node's derived row (kind, time, label) is computed again whenever a fact about it, or about an activity it
borrows its time from, arrives (`facts.py`). `GET /graph` is then a few indexed SQL queries whatever the size of
the log: the first view reads the first nodes of an index in drawing order, filters become conditions
(`candidates.py`), a neighbourhood a recursive query over the links.

Its tables are in `graph_schema.py`; a view is drawn by `graph_drawing.py`, whether a step changed the first view
is told by `graph_first_view.py`, and what the index holds about a resource is read by `graph_statements.py`.
"""

from __future__ import annotations

import logging
import sqlite3
from collections.abc import Collection, Sequence
from pathlib import Path
from time import monotonic

from pyoxigraph import Quad

from segb_server.backend.services.graph.candidates import FIRST_VIEW, CandidateQuery, GraphRequest
from segb_server.backend.services.graph.facts import (
    CATEGORY,
    DRAWN_LITERALS,
    GENERATED_AT,
    RDF_TYPE,
    TERMS,
    TIMES,
    Facts,
    display_label,
    local_name,
)
from segb_server.backend.services.graph.neighbourhoods import MAX_KEPT_REACH, KeptNeighbourhoods
from segb_server.backend.services.views import terms
from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.graph_drawing import draw, nodes_of
from segb_server.backend.services.views.graph_first_view import (
    first_view_changed,
    first_view_cutoff,
    new_first_view,
    node_rows,
    subjects_and_targets,
)
from segb_server.backend.services.views.graph_schema import SCHEMA, SCHEMA_DIGEST, TABLES
from segb_server.backend.services.views.graph_statements import kept_statements
from segb_server.backend.services.views.signal import ChangeSignal
from segb_server.backend.store.base import Store, Term

__all__ = [
    "CATEGORY",
    "FIRST_VIEW",
    "GENERATED_AT",
    "RDF_TYPE",
    "TIMES",
    "GraphIndex",
    "GraphRequest",
    "display_label",
    "local_name",
]

logger = logging.getLogger("segb.graph")

INDEX_VERSION = "7"  # bump when the stored rows change meaning: the index is then built again
# While the first view was asked for this recently, the keeper draws it again as soon as a step changes it: the
# viewer's next request (live viewers fetch on every change) finds it drawn. Nobody watching, nothing is drawn.
FIRST_VIEW_WATCHED_SECONDS = 120.0
BUILD_BATCH = 20_000  # triples read from the store at a time while building
CHANGES_KEPT_STEPS = 2_000  # journal steps the change log covers (a neighbourhood kept longer is drawn again)
STORED_VERSION = f"{INDEX_VERSION}-{SCHEMA_DIGEST}"  # what an index records as its version


class GraphIndex:
    name = "graph"

    def __init__(self, store: Store, path: Path | None, detail_literals: Collection[str] = ()) -> None:
        self.store = store
        self.db = ViewDatabase(path, SCHEMA)
        # Literals kept whole, beside those that name and place nodes, so `statements` can stand in for the
        # store when a resource's summary needs only these (an explanation's texts, versions, confidences).
        self.kept_literals = DRAWN_LITERALS | frozenset(detail_literals)
        self._facts = Facts(self.kept_literals)
        self.db.on_rollback(self._facts.forget)  # ids and lists of types made in a failed step went with it
        self.ready = False
        # The journal entry of the last change to what is drawn: live viewers fetch their view again when it
        # moves. Kept in memory by the process that keeps the index, read by `follow` in the others.
        self.changed_through = 0
        self.changed = ChangeSignal()  # wakes this process's live viewers when `changed_through` moves
        self._first_view: tuple[int, dict[str, object]] | None = None  # (graph_state.first_view, the view)
        self._first_view_asked = -FIRST_VIEW_WATCHED_SECONDS  # monotonic time of the last request for it
        self._drawing_first_view = False  # the keeper is drawing a changed first view
        self._neighbourhoods = KeptNeighbourhoods()

    # --- KeptView ----------------------------------------------------------------------------------

    def stored_through(self) -> int | None:
        row = self.db.reader().execute("SELECT version, through FROM graph_state").fetchone()
        return row[1] if row is not None and row[0] == STORED_VERSION else None

    def follow(self) -> int | None:
        row = self.db.reader().execute("SELECT version, through, changed FROM graph_state").fetchone()
        if row is None or row[0] != STORED_VERSION:
            return None
        self.changed_through = row[2]
        return int(row[1])

    def build(self, through: int) -> None:
        with self.db.writing() as connection:
            # Made again, not emptied: an index of an earlier version may have other columns.
            # graph_details: version 4's, the literals kept whole; graph_types: version 6's, each node's types
            for table in (*TABLES, "graph_details", "graph_types"):
                connection.execute(f"DROP TABLE IF EXISTS {table}")
            for statement in SCHEMA:
                connection.execute(statement)
            self._facts.forget()
            _set_through(connection, through, changed=True)
            new_first_view(connection)
            connection.execute("UPDATE graph_state SET changes_from = ?", (through,))
            for batch in self.store.batches(BUILD_BATCH):
                self._facts.store(connection, batch)
            nodes = [row[0] for row in connection.execute("SELECT id FROM graph_nodes ORDER BY id")]
            self._facts.derive(connection, nodes)
        self.prepared()
        self.changed_through = through
        self.changed.notify()
        logger.info("graph index built: %d nodes", len(nodes))

    def update(self, delta: Delta, through: int) -> None:
        quads = delta.quads
        with self.db.writing() as connection:
            cutoff = first_view_cutoff(connection)
            before = node_rows(connection, terms.lookup(connection, TERMS, subjects_and_targets(quads)).values())
            touched, links = self._facts.store(connection, quads)
            if touched:
                derived = sorted(touched | self._facts.borrowers(connection, touched))
                before |= node_rows(connection, [node for node in derived if node not in before])
                self._facts.derive(connection, derived)
                if first_view_changed(cutoff, before, node_rows(connection, derived), links):
                    connection.execute("UPDATE graph_state SET first_view = first_view + 1")
                    # Set before the new generation is committed: a request meanwhile gets the view before.
                    self._drawing_first_view = monotonic() - self._first_view_asked < FIRST_VIEW_WATCHED_SECONDS
                _record_changes(connection, derived, through)
            _set_through(connection, through, changed=bool(touched))
        if self._drawing_first_view:
            try:
                self._kept_first_view(self.db.reader(), keeper=True)  # before live viewers hear of the change
            finally:
                self._drawing_first_view = False
        if touched:
            self.changed_through = through
            self.changed.notify()

    def prepared(self) -> None:
        """Draw the first view now, built or caught up: the first visitor would otherwise wait for it."""
        self._kept_first_view(self.db.reader())

    def clear(self, through: int) -> None:
        with self.db.writing() as connection:
            for table in TABLES:
                connection.execute(f"DELETE FROM {table}")
            self._facts.forget()
            _set_through(connection, through, changed=True)
            new_first_view(connection)
            connection.execute("UPDATE graph_state SET changes_from = ?", (through,))
        self.changed_through = through
        self.changed.notify()

    def close(self) -> None:
        self.db.close()

    # --- reading -------------------------------------------------------------------------------------

    def view(self, request: GraphRequest) -> dict[str, object]:
        """The nodes and edges to draw, most relevant first, cut at `request.limit`. The first view is kept
        until a change reaches what it draws: under a stream of posts, the new nodes sort after its last."""
        connection = self.db.reader()
        if request.focus:
            return self._neighbourhoods.view(connection, request, lambda: self._drawn_and_reached(connection, request))
        if request != FIRST_VIEW:
            return self._view(connection, request)
        self._first_view_asked = monotonic()
        return self._kept_first_view(connection)

    def _kept_first_view(self, connection: sqlite3.Connection, *, keeper: bool = False) -> dict[str, object]:
        """The first view, drawn again only when its generation moved since it was kept. While the keeper draws
        the next one, a request gets the one before: its `through` (`changed_through`, which moves once the
        keeper is done) still says what that view includes."""
        state = connection.execute("SELECT first_view, nodes FROM graph_state").fetchone()
        if state is None:
            return self._view(connection, FIRST_VIEW)
        generation, total = state  # read before the view: a view kept is never older than its generation
        kept = self._first_view
        stale = kept is None or kept[0] != generation
        if stale and (keeper or kept is None or not self._drawing_first_view):
            kept = self._first_view = (generation, self._view(connection, FIRST_VIEW))
        assert kept is not None
        view = kept[1]
        return {**view, "total_nodes": total if view["truncated"] else view["total_nodes"]}

    def _drawn_and_reached(
        self, connection: sqlite3.Connection, request: GraphRequest
    ) -> tuple[dict[str, object], frozenset[int] | None]:
        """A neighbourhood's view, and every node within its depth (what a change must write to change it; None
        past `MAX_KEPT_REACH` nodes)."""
        ids = terms.lookup(connection, TERMS, request.iris())
        if request.focus not in ids:  # not in the index yet: nothing to keep the view by until it is
            return self._view(connection, request), None
        text, arguments = CandidateQuery(request, ids).reached()
        found = [row[0] for row in connection.execute(f"{text} LIMIT ?", [*arguments, MAX_KEPT_REACH + 1])]
        reached = frozenset(found) if len(found) <= MAX_KEPT_REACH else None
        return self._view(connection, request), reached

    def _view(self, connection: sqlite3.Connection, request: GraphRequest) -> dict[str, object]:
        """A view drawn from the tables now: every drawing goes through here."""
        return draw(connection, request)

    def nodes(self, iris: Collection[str]) -> dict[str, dict[str, object]]:
        """The nodes of these IRIs as a view draws them (label, kind, time), by IRI; those it holds no node of
        are left out."""
        return nodes_of(self.db.reader(), iris)

    def statements(
        self, iris: Sequence[str], incoming: Collection[str], incoming_limit: int, pending: Sequence[Quad] = ()
    ) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
        """What the index holds about `iris`, as rows of the store's resource queries (`resource`, `predicate`,
        `value`): every link and type from each, its kept literals, and up to `incoming_limit` + 1 links with
        the `incoming` predicates pointing at each. `pending`: triples the store has and the index does not
        have yet (applied steps on their way to it), told as if the index held them."""
        return kept_statements(self.db.reader(), self.kept_literals, iris, incoming, incoming_limit, pending)


def _record_changes(connection: sqlite3.Connection, nodes: Sequence[int], through: int) -> None:
    """Log the nodes step `through` wrote, for kept neighbourhoods, and forget the steps past what the log keeps."""
    connection.executemany("INSERT INTO graph_changes VALUES (?, ?)", [(through, node) for node in nodes])
    oldest = through - CHANGES_KEPT_STEPS
    if connection.execute("SELECT 1 FROM graph_changes WHERE seq <= ? LIMIT 1", (oldest,)).fetchone():
        connection.execute("DELETE FROM graph_changes WHERE seq <= ?", (oldest,))
        connection.execute("UPDATE graph_state SET changes_from = MAX(changes_from, ?)", (oldest,))


def _set_through(connection: sqlite3.Connection, through: int, *, changed: bool) -> None:
    connection.execute(
        "INSERT INTO graph_state (id, version, through, changed) VALUES (1, ?, ?, ?) ON CONFLICT (id) DO UPDATE SET "
        "version = excluded.version, through = excluded.through, changed = CASE WHEN ? THEN excluded.through "
        "ELSE changed END",
        (STORED_VERSION, through, through, changed),
    )
