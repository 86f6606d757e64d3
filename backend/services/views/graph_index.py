"""The drawable graph kept as indexed rows, current with each applied journal step (a `KeptView`).

The facts (links, types, the literals it keeps) are stored as they arrive, every IRI as a number (`views/terms.py`);
each node's derived row (kind, time, label) is computed again whenever a fact about it, or about an activity it
borrows its time from, arrives (`facts.py`). `GET /graph` is then a few indexed SQL queries whatever the size of
the log: the first view reads the first nodes of an index in drawing order, filters become conditions
(`candidates.py`), a neighbourhood a recursive query over the links.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sqlite3
from collections.abc import Collection, Iterable, Sequence
from functools import lru_cache
from pathlib import Path
from time import monotonic, time_ns
from typing import Any

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.graph.candidates import FIRST_VIEW, CandidateQuery, GraphRequest
from segb_server.backend.services.graph.facts import (
    CATEGORY,
    DRAWN_LITERALS,
    GENERATED_AT,
    PROV,
    RDF_TYPE,
    TERMS,
    TIMES,
    Facts,
    chunks,
    display_label,
    local_name,
    node_time,
    typed_literal,
)
from segb_server.backend.services.graph.neighbourhoods import MAX_KEPT_REACH, KeptNeighbourhoods
from segb_server.backend.services.views import terms
from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.signal import ChangeSignal
from segb_server.backend.store.base import Store, Term
from segb_server.backend.vocabulary import KINDS, compact

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

TABLES = (
    "graph_state",
    "graph_terms",
    "graph_literals",
    "graph_links",
    "graph_typesets",
    "graph_nodes",
    "graph_changes",
)
CHANGES_KEPT_STEPS = 2_000  # journal steps the change log covers (a neighbourhood kept longer is drawn again)
SCHEMA = [
    # nodes: how many rows graph_nodes holds (nodes are only ever added, until a clearing), for the first view's
    # total without counting them; changed: the entry of the last change to what is drawn (for live viewers of
    # every API process)
    # first_view: changes whenever the first view (`FIRST_VIEW`) would draw something else, so every process may
    # keep that view, the one each visit opens with, until it does
    # changes_from: the entry after which `graph_changes` holds every node each step wrote (`neighbourhoods`)
    # literals: how many literals the index was given (their numbers in `graph_literals`)
    "CREATE TABLE IF NOT EXISTS graph_state (id INTEGER PRIMARY KEY CHECK (id = 1), version TEXT, through INTEGER, "
    "nodes INTEGER NOT NULL DEFAULT 0, changed INTEGER NOT NULL DEFAULT 0, first_view INTEGER NOT NULL DEFAULT 0, "
    "changes_from INTEGER NOT NULL DEFAULT 0, literals INTEGER NOT NULL DEFAULT 0)",
    # every IRI once: nodes, predicates, datatypes (views/terms.py; classes are in the lists of types)
    *terms.schema(TERMS),
    "CREATE TABLE IF NOT EXISTS graph_changes (seq INTEGER NOT NULL, node INTEGER NOT NULL)",
    "CREATE INDEX IF NOT EXISTS graph_changes_by_seq ON graph_changes (seq)",
    # the literals kept (those that name and place nodes, and `detail_literals`) whole, each node's together in
    # the order they came (seq: graph_state.literals when it came; a node's name is its first, its time its
    # last); datatype is NULL for a language-tagged string
    "CREATE TABLE IF NOT EXISTS graph_literals (node INTEGER NOT NULL, seq INTEGER NOT NULL, "
    "predicate INTEGER NOT NULL, value TEXT NOT NULL, datatype INTEGER, language TEXT, PRIMARY KEY (node, seq)) "
    "WITHOUT ROWID",
    "CREATE TABLE IF NOT EXISTS graph_links (source INTEGER, predicate INTEGER, target INTEGER, "
    "PRIMARY KEY (source, predicate, target)) WITHOUT ROWID",
    "CREATE INDEX IF NOT EXISTS graph_links_by_target ON graph_links (target, predicate, source)",
    # the distinct lists of a node's types (IRIs, sorted, as JSON): a few dozen lists for thousands of nodes, each
    # node holding its list's id (`typeset`)
    "CREATE TABLE IF NOT EXISTS graph_typesets (id INTEGER PRIMARY KEY, types TEXT NOT NULL UNIQUE)",
    # rank: the kind's place in KINDS; instant: the time in microseconds (UNTIMED when none); tie: what orders
    # nodes of one kind and instant (the robots, the people), the same however they arrived (`facts.tie_of`: a
    # text or a number, so the column has no type that would turn one into the other);
    # time: only a time its instant does not spell (`facts.kept_time`); folded: the label as a search compares
    # it, when SQLite's lower() would not give it (`facts._folded`)
    "CREATE TABLE IF NOT EXISTS graph_nodes (id INTEGER PRIMARY KEY, rank INTEGER NOT NULL, "
    "instant INTEGER NOT NULL, tie NOT NULL, time TEXT, label TEXT NOT NULL, folded TEXT, "
    "typeset INTEGER NOT NULL)",
    "CREATE INDEX IF NOT EXISTS graph_nodes_order ON graph_nodes (rank, instant, tie, id)",
    "CREATE INDEX IF NOT EXISTS graph_nodes_typeset ON graph_nodes (typeset)",  # the nodes of a class
]
# What an index records as its version: a change to the tables is a new version too, so an index written before
# it is built again instead of failing on a column it lacks.
_SCHEMA_DIGEST = hashlib.sha256("\n".join(SCHEMA).encode()).hexdigest()[:12]
STORED_VERSION = f"{INDEX_VERSION}-{_SCHEMA_DIGEST}"


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
            _new_first_view(connection)
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
            cutoff = _first_view_cutoff(connection)
            before = _node_rows(connection, terms.lookup(connection, TERMS, _subjects_and_targets(quads)).values())
            touched, links = self._facts.store(connection, quads)
            if touched:
                derived = sorted(touched | self._facts.borrowers(connection, touched))
                before |= _node_rows(connection, [node for node in derived if node not in before])
                self._facts.derive(connection, derived)
                if _first_view_changed(cutoff, before, _node_rows(connection, derived), links):
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
            _new_first_view(connection)
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
        ids = terms.lookup(connection, TERMS, request.iris())
        if request.focus and (request.focus not in ids or not _is_node(connection, ids[request.focus])):
            return {"nodes": [], "edges": [], "truncated": False, "total_nodes": 0, "matches": []}
        query = CandidateQuery(request, ids)
        found = connection.execute(*query.ordered(request.limit + 1)).fetchall()
        truncated = len(found) > request.limit
        kept = found[: request.limit]
        nodes = [_node(row[0], row[1], *row[4:]) for row in kept]
        total = len(kept) if not truncated else _total(connection, query)
        needle = request.q.casefold() if request.q else None
        return {
            "nodes": nodes,
            "edges": _edges(connection, {row[3]: row[4] for row in kept}),
            "truncated": truncated,
            "total_nodes": total,
            "matches": [str(node["id"]) for node in nodes if needle and _matches(node, needle)],
        }

    def statements(
        self, iris: Sequence[str], incoming: Collection[str], incoming_limit: int, pending: Sequence[Quad] = ()
    ) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
        """What the index holds about `iris`, as rows of the store's resource queries (`resource`, `predicate`,
        `value`): every link and type from each, its kept literals, and up to `incoming_limit` + 1 links with
        the `incoming` predicates pointing at each. `pending`: triples the store has and the index does not
        have yet (applied steps on their way to it), told as if the index held them."""
        connection = self.db.reader()
        wanted = list(dict.fromkeys(iris))
        ids = terms.lookup(connection, TERMS, [*wanted, *incoming])
        nodes = [ids[iri] for iri in wanted if iri in ids]
        outgoing: list[dict[str, Term]] = []
        pointing: list[dict[str, Term]] = []
        type_predicate = NamedNode(RDF_TYPE)
        for chunk in chunks(nodes):
            marks = ", ".join("?" * len(chunk))
            for source, predicate, target in connection.execute(
                f"SELECT s.text, p.text, o.text FROM graph_links l JOIN graph_terms s ON s.id = l.source "
                f"JOIN graph_terms p ON p.id = l.predicate JOIN graph_terms o ON o.id = l.target "
                f"WHERE l.source IN ({marks})",
                chunk,
            ):
                outgoing.append({"resource": NamedNode(source), "predicate": NamedNode(predicate),
                                 "value": NamedNode(target)})  # fmt: skip
            for iri, listed in connection.execute(
                f"SELECT t.text, s.types FROM graph_nodes n JOIN graph_terms t ON t.id = n.id "
                f"JOIN graph_typesets s ON s.id = n.typeset WHERE n.id IN ({marks})",
                chunk,
            ):
                outgoing += [{"resource": NamedNode(iri), "predicate": type_predicate, "value": NamedNode(type_)}
                             for type_ in json.loads(listed)]  # fmt: skip
            for iri, predicate, value, datatype, language in connection.execute(
                f"SELECT DISTINCT s.text, p.text, l.value, d.text, l.language FROM graph_literals l "
                f"JOIN graph_terms s ON s.id = l.node JOIN graph_terms p ON p.id = l.predicate "
                f"LEFT JOIN graph_terms d ON d.id = l.datatype WHERE l.node IN ({marks})",
                chunk,
            ):
                outgoing.append({"resource": NamedNode(iri), "predicate": NamedNode(predicate),
                                 "value": typed_literal(value, datatype, language)})  # fmt: skip
        predicates = sorted(ids[predicate] for predicate in incoming if predicate in ids)
        marks = ", ".join("?" * len(predicates))
        for iri in wanted:
            if iri not in ids or not predicates:
                continue
            for predicate, source in connection.execute(
                f"SELECT p.text, s.text FROM (SELECT predicate, source FROM graph_links WHERE target = ? "
                f"AND predicate IN ({marks}) LIMIT ?) l JOIN graph_terms p ON p.id = l.predicate "
                f"JOIN graph_terms s ON s.id = l.source",
                [ids[iri], *predicates, incoming_limit + 1],
            ):
                pointing.append({"resource": NamedNode(iri), "predicate": NamedNode(predicate),
                                 "value": NamedNode(source)})  # fmt: skip
        if not pending:
            return outgoing, pointing
        more_out, more_in = _pending_statements(pending, set(iris), set(incoming), self.kept_literals)
        # A pending triple may have reached the index since its rows were read: each statement is told once.
        return _unique(outgoing + more_out), _unique(pointing + more_in)


def _pending_statements(
    quads: Sequence[Quad], iris: set[str], incoming: set[str], kept_literals: frozenset[str]
) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
    """The rows `GraphIndex.statements` would read about `iris` once `quads` are in the index: what the facts
    keep of them (links, types, kept literals, from named subjects only)."""
    outgoing: list[dict[str, Term]] = []
    pointing: list[dict[str, Term]] = []
    for quad in quads:
        subject, predicate, value = quad.subject, quad.predicate, quad.object
        if not isinstance(subject, NamedNode):
            continue
        if isinstance(value, NamedNode):
            if subject.value in iris:
                outgoing.append({"resource": subject, "predicate": predicate, "value": value})
            if value.value in iris and predicate.value in incoming and predicate.value != RDF_TYPE:
                pointing.append({"resource": value, "predicate": predicate, "value": subject})
        elif isinstance(value, Literal) and subject.value in iris and predicate.value in kept_literals:
            outgoing.append({"resource": subject, "predicate": predicate, "value": value})
    return outgoing, pointing


def _unique(rows: list[dict[str, Term]]) -> list[dict[str, Term]]:
    return list({(row["resource"], row["predicate"], row["value"]): row for row in rows}.values())


def _is_node(connection: sqlite3.Connection, node: int) -> bool:
    return connection.execute("SELECT 1 FROM graph_nodes WHERE id = ?", (node,)).fetchone() is not None


def _node(rank: int, instant: int, iri: str, kept: str | None, label: str, types: str) -> dict[str, object]:
    node: dict[str, object] = {"id": iri, "label": label, "kind": KINDS[rank], "types": list(_types(types))}
    time = node_time(kept, instant)
    if time:
        node["time"] = time
    return node


@lru_cache(maxsize=4096)
def _types(listed: str) -> tuple[str, ...]:
    """A node's stored type list as drawn (CURIEs), made once: a graph of thousands of nodes has a few dozen
    distinct lists."""
    return tuple(sorted(compact(type_) for type_ in json.loads(listed)))


def _total(connection: sqlite3.Connection, query: CandidateQuery) -> int:
    """How many nodes the request allows: kept as a count for the unfiltered view, counted otherwise."""
    if query.unfiltered:
        return int(connection.execute("SELECT nodes FROM graph_state").fetchone()[0])
    return int(connection.execute(*query.count()).fetchone()[0])


def _edges(connection: sqlite3.Connection, drawn: dict[int, str]) -> list[dict[str, str]]:
    """The links between drawn nodes (id → IRI). The client doubles most links with a PROV copy
    (segb:wasPerformedBy + prov:wasAssociatedWith, schema:sender + prov:wasAttributedTo, ...); drawing both
    only doubles every arrow."""
    listed = json.dumps(list(drawn))
    found = connection.execute(
        "SELECT source, predicate, target FROM graph_links WHERE source IN (SELECT value FROM json_each(?)) "
        "AND target IN (SELECT value FROM json_each(?))",
        (listed, listed),
    ).fetchall()
    predicates = terms.texts_of(connection, TERMS, {predicate for _, predicate, _ in found})
    links = sorted((drawn[s], predicates[p], drawn[o]) for s, p, o in found)
    primary_pairs = {(s, o) for s, p, o in links if not p.startswith(PROV)}
    labels = {p: local_name(p) for p in {p for _, p, _ in links}}  # a few predicates label thousands of links
    return [
        {"id": f"{s} {p} {o}", "source": s, "target": o, "predicate": p, "label": labels[p]}
        for s, p, o in links
        if not (p.startswith(PROV) and (s, o) in primary_pairs)
    ]


def _matches(node: dict[str, object], needle: str) -> bool:
    return needle in str(node["label"]).casefold() or needle in str(node["id"]).casefold()


# The first view's nodes are the first rows of graph_nodes in this order (`CandidateQuery` with no filter).
_FIRST_VIEW_ORDER = "ORDER BY rank, instant, tie, id"
_ROW_COLUMNS = "id, rank, instant, tie, time, label, typeset"  # the sort key follows the id


def _first_view_cutoff(connection: sqlite3.Connection) -> tuple[Any, ...] | None:
    """The sort key of the last row the first view reads (its limit and one more, which tells whether it is cut
    off); None while there are fewer nodes, when every node is in it."""
    return connection.execute(
        f"SELECT rank, instant, tie, id FROM graph_nodes {_FIRST_VIEW_ORDER} LIMIT 1 OFFSET ?", (FIRST_VIEW.limit,)
    ).fetchone()


def _node_rows(connection: sqlite3.Connection, nodes: Iterable[int]) -> dict[int, tuple[Any, ...]]:
    rows: dict[int, tuple[Any, ...]] = {}
    for chunk in chunks(sorted(nodes)):
        marks = ", ".join("?" * len(chunk))
        for row in connection.execute(f"SELECT {_ROW_COLUMNS} FROM graph_nodes WHERE id IN ({marks})", chunk):
            rows[row[0]] = row
    return rows


def _first_view_changed(
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


def _subjects_and_targets(quads: Iterable[Quad]) -> set[str]:
    """The IRIs the facts may add as nodes: named subjects and named objects."""
    return {term.value for quad in quads for term in (quad.subject, quad.object) if isinstance(term, NamedNode)}


def _new_first_view(connection: sqlite3.Connection) -> None:
    """A first view unlike any kept one (after a build or a clearing, which start the counter again)."""
    connection.execute("UPDATE graph_state SET first_view = ?", (time_ns(),))


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
