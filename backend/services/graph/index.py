"""The drawable graph kept as indexed rows, current with each applied journal step (a `KeptView`).

What is drawn: every link between two resources (`rdf:type` gives node types instead) and the literals that
name and place nodes (`DRAWN_LITERALS`); other literals stay in node details (`GET /resource`). The facts are
stored as they arrive (types, literals, links); each node's derived row (kind, time, label) is computed again
whenever a fact about it, or about an activity it borrows its time from, arrives. `GET /graph` is then a few
indexed SQL queries whatever the size of the log: the first view reads the first nodes of an index in drawing
order, filters become conditions, a neighbourhood a recursive query over the links.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections import defaultdict
from collections.abc import Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import lru_cache
from pathlib import Path
from time import monotonic, time_ns
from typing import Any

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.graph.neighbourhoods import MAX_KEPT_REACH, KeptNeighbourhoods
from segb_server.backend.services.upkeep.database import ViewDatabase
from segb_server.backend.services.upkeep.delta import Delta
from segb_server.backend.services.upkeep.signal import ChangeSignal
from segb_server.backend.services.values import iso_time
from segb_server.backend.store.base import Store, Term
from segb_server.backend.vocabulary import KINDS, PREFIXES, Kind, compact, kind_of

logger = logging.getLogger("segb.graph")

INDEX_VERSION = "4"  # bump when the stored rows change meaning: the index is then built again
RDF_TYPE = PREFIXES["rdf"] + "type"
# Display name predicates, best first.
LABELS = [PREFIXES["foaf"] + "firstName", PREFIXES["schema"] + "name", PREFIXES["rdfs"] + "label"]
TEXT = PREFIXES["schema"] + "text"
DESCRIPTION = PREFIXES["schema"] + "description"
INTENSITY = PREFIXES["onyx"] + "hasEmotionIntensity"
CATEGORY = PREFIXES["onyx"] + "hasEmotionCategory"
# Own time of a node, best first. Messages and emotions borrow the time of the activity behind them.
TIMES = [PREFIXES["prov"] + name for name in ("startedAtTime", "endedAtTime", "generatedAtTime")]
GENERATED_AT = PREFIXES["prov"] + "generatedAtTime"
WAS_GENERATED_BY = PREFIXES["prov"] + "wasGeneratedBy"
PRODUCED = PREFIXES["segb"] + "producedEntityResult"
HAS_EMOTION = PREFIXES["onyx"] + "hasEmotion"
PERFORMED_BY = PREFIXES["segb"] + "wasPerformedBy"
ATTRIBUTED_TO = PREFIXES["prov"] + "wasAttributedTo"
PROV = PREFIXES["prov"]
DRAWN_LITERALS = frozenset([*LABELS, TEXT, DESCRIPTION, *TIMES, INTENSITY])
MAX_LABEL = 60
UNTIMED = "~"  # sorts after every instant
CHUNK = 400  # IRIs per IN (…) list
# While the first view was asked for this recently, the keeper draws it again as soon as a step changes it: the
# viewer's next request (live viewers fetch on every change) finds it drawn. Nobody watching, nothing is drawn.
FIRST_VIEW_WATCHED_SECONDS = 120.0

TABLES = (
    "graph_state",
    "graph_types",
    "graph_literals",
    "graph_details",
    "graph_links",
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
    "CREATE TABLE IF NOT EXISTS graph_state (id INTEGER PRIMARY KEY CHECK (id = 1), version TEXT, through INTEGER, "
    "nodes INTEGER NOT NULL DEFAULT 0, changed INTEGER NOT NULL DEFAULT 0, first_view INTEGER NOT NULL DEFAULT 0, "
    "changes_from INTEGER NOT NULL DEFAULT 0)",
    "CREATE TABLE IF NOT EXISTS graph_changes (seq INTEGER NOT NULL, iri TEXT NOT NULL)",
    "CREATE INDEX IF NOT EXISTS graph_changes_by_seq ON graph_changes (seq)",
    "CREATE TABLE IF NOT EXISTS graph_types (iri TEXT, type TEXT, PRIMARY KEY (iri, type)) WITHOUT ROWID",
    "CREATE TABLE IF NOT EXISTS graph_literals (iri TEXT, predicate TEXT, value TEXT, PRIMARY KEY (iri, predicate))"
    " WITHOUT ROWID",
    # every value of the literals kept whole for resource summaries (`detail_literals`), with datatype or language
    "CREATE TABLE IF NOT EXISTS graph_details (iri TEXT, predicate TEXT, value TEXT, datatype TEXT, language TEXT, "
    "PRIMARY KEY (iri, predicate, value, datatype, language)) WITHOUT ROWID",
    "CREATE TABLE IF NOT EXISTS graph_links (source TEXT, predicate TEXT, target TEXT, "
    "PRIMARY KEY (source, predicate, target)) WITHOUT ROWID",
    "CREATE INDEX IF NOT EXISTS graph_links_by_target ON graph_links (target, predicate, source)",
    # kind, time, label, types (a JSON list of CURIEs): derived from the facts; instant: the time as a fixed-width
    # UTC text that sorts as time
    "CREATE TABLE IF NOT EXISTS graph_nodes (iri TEXT PRIMARY KEY, kind TEXT NOT NULL, rank INTEGER NOT NULL, "
    "time TEXT, instant TEXT NOT NULL, label TEXT NOT NULL, search TEXT NOT NULL, types TEXT NOT NULL) "
    "WITHOUT ROWID",
    "CREATE INDEX IF NOT EXISTS graph_nodes_order ON graph_nodes (rank, instant, iri)",
    "CREATE INDEX IF NOT EXISTS graph_nodes_instant ON graph_nodes (instant)",
]
RANK = {kind: index for index, kind in enumerate(KINDS)}
# What an index records as its version: a change to the tables is a new version too, so an index written before
# it is built again instead of failing on a column it lacks.
_SCHEMA_DIGEST = hashlib.sha256("\n".join(SCHEMA).encode()).hexdigest()[:12]
STORED_VERSION = f"{INDEX_VERSION}-{_SCHEMA_DIGEST}"


@dataclass(frozen=True)
class GraphRequest:
    limit: int = 1500
    robot: str | None = None
    since: str | None = None
    until: str | None = None
    types: tuple[str, ...] = ()
    focus: str | None = None
    depth: int = 1
    q: str | None = None


FIRST_VIEW = GraphRequest()  # the kg-graph's first view: no filter, the default limit


class GraphIndex:
    name = "graph"

    def __init__(self, store: Store, path: Path | None, detail_literals: Collection[str] = ()) -> None:
        self.store = store
        self.db = ViewDatabase(path, SCHEMA)
        # Literals kept whole, beside those that name and place nodes, so `statements` can stand in for the
        # store when a resource's summary needs only these (an explanation's texts, versions, confidences).
        self.kept_literals = DRAWN_LITERALS | frozenset(detail_literals)
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
            for table in TABLES:
                connection.execute(f"DROP TABLE IF EXISTS {table}")
            for statement in SCHEMA:
                connection.execute(statement)
            _set_through(connection, through, changed=True)
            _new_first_view(connection)
            connection.execute("UPDATE graph_state SET changes_from = ?", (through,))
            for batch in self.store.batches(20_000):
                _store_facts(connection, batch, self.kept_literals)
            iris = [row[0] for row in connection.execute("SELECT iri FROM graph_nodes")]
            _derive(connection, iris)
        self.prepared()
        self.changed_through = through
        self.changed.notify()
        logger.info("graph index built: %d nodes", len(iris))

    def update(self, delta: Delta, through: int) -> None:
        quads = delta.quads
        with self.db.writing() as connection:
            cutoff = _first_view_cutoff(connection)
            before = _node_rows(connection, _subjects_and_targets(quads))
            touched, links = _store_facts(connection, quads, self.kept_literals)
            if touched:
                derived = sorted(touched | _borrowers(connection, touched))
                before |= _node_rows(connection, [iri for iri in derived if iri not in before])
                _derive(connection, derived)
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

    def _kept_first_view(self, connection: Any, *, keeper: bool = False) -> dict[str, object]:
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
        self, connection: Any, request: GraphRequest
    ) -> tuple[dict[str, object], frozenset[str] | None]:
        """A neighbourhood's view, and every node within its depth (what a change must write to change it; None
        past `MAX_KEPT_REACH` nodes)."""
        text, arguments = _CandidateQuery(request).reached()
        found = [row[0] for row in connection.execute(f"{text} LIMIT ?", [*arguments, MAX_KEPT_REACH + 1])]
        reached = frozenset(found) if len(found) <= MAX_KEPT_REACH else None
        return self._view(connection, request), reached

    def _view(self, connection: Any, request: GraphRequest) -> dict[str, object]:
        query = _CandidateQuery(request)
        if (
            request.focus
            and not connection.execute("SELECT 1 FROM graph_nodes WHERE iri = ?", (request.focus,)).fetchone()
        ):
            return {"nodes": [], "edges": [], "truncated": False, "total_nodes": 0, "matches": []}
        found = connection.execute(*query.ordered(request.limit + 1)).fetchall()
        truncated = len(found) > request.limit
        nodes = [_node(*row) for row in found[: request.limit]]
        kept = [str(node["id"]) for node in nodes]
        total = len(kept) if not truncated else _total(connection, query)
        needle = request.q.casefold() if request.q else None
        return {
            "nodes": nodes,
            "edges": _edges(connection, kept),
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
        outgoing: list[dict[str, Term]] = []
        pointing: list[dict[str, Term]] = []
        type_predicate = NamedNode(RDF_TYPE)
        for chunk in _chunks(list(dict.fromkeys(iris))):
            marks = ", ".join("?" * len(chunk))
            for source, predicate, target in connection.execute(
                f"SELECT source, predicate, target FROM graph_links WHERE source IN ({marks})", chunk
            ):
                outgoing.append({"resource": NamedNode(source), "predicate": NamedNode(predicate),
                                 "value": NamedNode(target)})  # fmt: skip
            for iri, type_ in connection.execute(f"SELECT iri, type FROM graph_types WHERE iri IN ({marks})", chunk):
                outgoing.append({"resource": NamedNode(iri), "predicate": type_predicate, "value": NamedNode(type_)})
            for iri, predicate, value, datatype, language in connection.execute(
                f"SELECT iri, predicate, value, datatype, language FROM graph_details WHERE iri IN ({marks})", chunk
            ):
                literal = (
                    Literal(value, language=language) if language else Literal(value, datatype=NamedNode(datatype))
                )
                outgoing.append({"resource": NamedNode(iri), "predicate": NamedNode(predicate), "value": literal})
        predicates = sorted(incoming)
        marks = ", ".join("?" * len(predicates))
        for iri in dict.fromkeys(iris):
            for predicate, source in connection.execute(
                f"SELECT predicate, source FROM graph_links WHERE target = ? AND predicate IN ({marks}) LIMIT ?",
                [iri, *predicates, incoming_limit + 1],
            ):
                pointing.append({"resource": NamedNode(iri), "predicate": NamedNode(predicate),
                                 "value": NamedNode(source)})  # fmt: skip
        if not pending:
            return outgoing, pointing
        more_out, more_in = _pending_statements(pending, set(iris), set(incoming), self.kept_literals)
        # A pending triple may have reached the index since its rows were read: each statement is told once.
        return _unique(outgoing + more_out), _unique(pointing + more_in)


class _CandidateQuery:
    """One SQL query choosing the nodes a request draws: each filter adds a common table expression of the
    IRIs it allows and a condition on the node; a focus adds the distances from it (recursive)."""

    def __init__(self, request: GraphRequest) -> None:
        self.ctes: list[str] = []
        self.arguments: list[object] = []
        self.conditions: list[str] = []
        self.condition_arguments: list[object] = []
        self.distance = False
        self.searched = False
        if request.robot:
            self._robot(request.robot)
        if request.since or request.until:
            self._window(request.since, request.until)
        if request.types:
            self._types(request.types)
        if request.q:
            self._search(request.q.casefold())
        if request.focus:
            self._focus(request.focus, request.depth)

    def _cte(self, text: str, *arguments: object) -> None:
        self.ctes.append(text)
        self.arguments.extend(arguments)

    def _robot(self, robot: str) -> None:
        """The robot, what it did and was attributed (activities, states), what those touched, and the
        emotions and humans one step further (through annotations and shared events)."""
        self._cte(
            "robot_seeds(iri) AS (SELECT ? UNION SELECT source FROM graph_links WHERE target = ? "
            "AND predicate IN (?, ?))",
            robot, robot, PERFORMED_BY, ATTRIBUTED_TO,
        )  # fmt: skip
        self._cte(
            "robot_around(iri) AS (SELECT iri FROM robot_seeds "
            "UNION SELECT l.target FROM robot_seeds s JOIN graph_links l ON l.source = s.iri "
            "UNION SELECT l.source FROM robot_seeds s JOIN graph_links l ON l.target = s.iri)"
        )
        self._cte(
            "robot_set(iri) AS (SELECT iri FROM robot_around UNION SELECT l.target FROM robot_around a "
            "JOIN graph_nodes n ON n.iri = a.iri AND n.kind IN ('emotion', 'shared-event') "
            "JOIN graph_links l ON l.source = a.iri)"
        )
        self.conditions.append("n.iri IN robot_set")

    def _window(self, since: str | None, until: str | None) -> None:
        """Timed nodes inside the window, and untimed nodes linked to one of them."""
        bounds, arguments = ["time IS NOT NULL"], []
        if since:
            bounds.append("instant >= ?")
            arguments.append(instant_of(since))
        if until:
            bounds.append("instant <= ?")
            arguments.append(instant_of(until))
        self._cte(f"window_timed(iri) AS (SELECT iri FROM graph_nodes WHERE {' AND '.join(bounds)})", *arguments)
        self._cte(
            "window_set(iri) AS (SELECT iri FROM window_timed "
            "UNION SELECT l.target FROM window_timed t JOIN graph_links l ON l.source = t.iri "
            "JOIN graph_nodes u ON u.iri = l.target AND u.time IS NULL "
            "UNION SELECT l.source FROM window_timed t JOIN graph_links l ON l.target = t.iri "
            "JOIN graph_nodes u ON u.iri = l.source AND u.time IS NULL)"
        )
        self.conditions.append("n.iri IN window_set")

    def _types(self, wanted: Sequence[str]) -> None:
        """Kinds (`robot`), class CURIEs (`oro:Robot`) or class IRIs."""
        kinds = [value for value in wanted if value in KINDS]
        classes = sorted({_expanded(value) for value in wanted if value not in KINDS})
        either = []
        if kinds:
            either.append(f"n.kind IN ({', '.join('?' * len(kinds))})")
            self.condition_arguments.extend(kinds)
        if classes:
            either.append(f"n.iri IN (SELECT iri FROM graph_types WHERE type IN ({', '.join('?' * len(classes))}))")
            self.condition_arguments.extend(classes)
        self.conditions.append(f"({' OR '.join(either)})")

    def _search(self, needle: str) -> None:
        """Nodes whose label or IRI holds the text (any case), among the nodes allowed so far, and their
        neighbours."""
        where = " AND ".join([*self.conditions, "instr(n.search, ?) > 0"])
        self._cte(f"hits(iri) AS (SELECT n.iri FROM graph_nodes n WHERE {where})", *self.condition_arguments, needle)
        self._cte(
            "hit_set(iri) AS (SELECT iri FROM hits "
            "UNION SELECT l.target FROM hits h JOIN graph_links l ON l.source = h.iri "
            "UNION SELECT l.source FROM hits h JOIN graph_links l ON l.target = h.iri)"
        )
        self.conditions.append("n.iri IN hit_set")
        self.searched = True

    def _focus(self, focus: str, depth: int) -> None:
        self._cte(
            "reach(iri, d) AS (SELECT ?, 0 "
            "UNION SELECT l.target, r.d + 1 FROM reach r JOIN graph_links l ON l.source = r.iri WHERE r.d < ? "
            "UNION SELECT l.source, r.d + 1 FROM reach r JOIN graph_links l ON l.target = r.iri WHERE r.d < ?)",
            focus, depth, depth,
        )  # fmt: skip
        self._cte("distance(iri, d) AS (SELECT iri, MIN(d) FROM reach GROUP BY iri)")
        self.distance = True

    def _select(self, columns: str) -> tuple[str, list[object]]:
        head = f"WITH RECURSIVE {', '.join(self.ctes)} " if self.ctes else ""
        join = " JOIN distance d ON d.iri = n.iri" if self.distance else ""
        where = f" WHERE {' AND '.join(self.conditions)}" if self.conditions else ""
        return f"{head}SELECT {columns} FROM graph_nodes n{join}{where}", [*self.arguments, *self.condition_arguments]

    @property
    def unfiltered(self) -> bool:
        return not self.ctes and not self.conditions

    def ordered(self, limit: int) -> tuple[str, list[object]]:
        """The nodes drawn, in drawing order, each as the columns `_node` takes."""
        text, arguments = self._select("n.iri, n.kind, n.time, n.label, n.types")
        order = "d.d, n.rank, n.instant, n.iri" if self.distance else "n.rank, n.instant, n.iri"
        if self.searched:  # what was searched for first, then its neighbours: a limit must not cut the hits
            order = "n.iri NOT IN hits, " + order
        return f"{text} ORDER BY {order} LIMIT ?", [*arguments, limit]

    def count(self) -> tuple[str, list[object]]:
        return self._select("COUNT(*)")

    def reached(self) -> tuple[str, list[object]]:
        """Every node within a focus request's depth, whatever its other filters."""
        assert self.distance, "only a request with a focus reaches nodes"
        return f"WITH RECURSIVE {', '.join(self.ctes)} SELECT iri FROM distance", list(self.arguments)


# --- facts and derived rows ----------------------------------------------------------------------------


@dataclass
class _Derived:
    kind: Kind
    time: str | None
    label: str


def _store_facts(
    connection: Any, quads: Iterable[Quad], kept_literals: frozenset[str]
) -> tuple[set[str], list[tuple[str, str, str]]]:
    """Store the drawable facts among `quads`, and the kept literals whole; the IRIs of the nodes they are
    about, and the links among them."""
    types: list[tuple[str, str]] = []
    literals: list[tuple[str, str, str]] = []
    details: list[tuple[str, str, str, str, str]] = []
    times: list[tuple[str, str, str]] = []
    links: list[tuple[str, str, str]] = []
    nodes: set[str] = set()
    for quad in quads:
        subject, predicate, value = quad.subject, quad.predicate.value, quad.object
        if not isinstance(subject, NamedNode):
            continue
        if isinstance(value, Literal):
            if predicate in kept_literals:
                language = value.language or ""
                details.append(
                    (subject.value, predicate, value.value, "" if language else value.datatype.value, language)
                )
            if predicate in DRAWN_LITERALS:
                (times if predicate in TIMES else literals).append((subject.value, predicate, value.value))
                nodes.add(subject.value)
        elif isinstance(value, NamedNode):
            nodes.add(subject.value)
            if predicate == RDF_TYPE:
                types.append((subject.value, value.value))
            else:
                links.append((subject.value, predicate, value.value))
                nodes.add(value.value)
    connection.executemany("INSERT OR IGNORE INTO graph_types VALUES (?, ?)", types)
    connection.executemany("INSERT OR IGNORE INTO graph_literals VALUES (?, ?, ?)", literals)  # the first name stays
    connection.executemany("INSERT OR REPLACE INTO graph_literals VALUES (?, ?, ?)", times)
    connection.executemany("INSERT OR IGNORE INTO graph_details VALUES (?, ?, ?, ?, ?)", details)
    connection.executemany("INSERT OR IGNORE INTO graph_links VALUES (?, ?, ?)", links)
    added = connection.executemany(
        "INSERT OR IGNORE INTO graph_nodes VALUES (?, 'other', ?, NULL, ?, '', '', '[]')",
        [(iri, RANK["other"], UNTIMED) for iri in nodes],
    ).rowcount
    connection.execute("UPDATE graph_state SET nodes = nodes + ?", (added,))
    return nodes, links


def _pending_statements(
    quads: Sequence[Quad], iris: set[str], incoming: set[str], kept_literals: frozenset[str]
) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
    """The rows `GraphIndex.statements` would read about `iris` once `quads` are in the index: what
    `_store_facts` keeps of them (links, types, kept literals, from named subjects only)."""
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


def _borrowers(connection: Any, touched: set[str]) -> set[str]:
    """Nodes whose time may come from a touched one: what a touched activity produced or generated, and the
    emotions of what it produced."""
    first: set[str] = set()
    for chunk in _chunks(sorted(touched)):
        marks = ", ".join("?" * len(chunk))
        first.update(
            row[0]
            for row in connection.execute(
                f"SELECT target FROM graph_links WHERE source IN ({marks}) AND predicate IN (?, ?) "
                f"UNION SELECT source FROM graph_links WHERE target IN ({marks}) AND predicate = ?",
                [*chunk, PRODUCED, HAS_EMOTION, *chunk, WAS_GENERATED_BY],
            )
        )
    second: set[str] = set()
    for chunk in _chunks(sorted(first - touched)):
        marks = ", ".join("?" * len(chunk))
        second.update(
            row[0]
            for row in connection.execute(
                f"SELECT target FROM graph_links WHERE source IN ({marks}) AND predicate = ?",
                [*chunk, HAS_EMOTION],
            )
        )
    return first | second


def _derive(connection: Any, iris: Sequence[str]) -> None:
    """Compute each node's kind, time and label again from its facts."""
    for chunk in _chunks(iris):
        marks = ", ".join("?" * len(chunk))
        types: dict[str, set[str]] = defaultdict(set)
        for iri, type_ in connection.execute(f"SELECT iri, type FROM graph_types WHERE iri IN ({marks})", chunk):
            types[iri].add(type_)
        literals: dict[str, dict[str, str]] = defaultdict(dict)
        for iri, predicate, value in connection.execute(
            f"SELECT iri, predicate, value FROM graph_literals WHERE iri IN ({marks})", chunk
        ):
            literals[iri][predicate] = value
        categories = dict(
            connection.execute(
                f"SELECT source, MIN(target) FROM graph_links WHERE source IN ({marks}) AND predicate = ? "
                "GROUP BY source",
                [*chunk, CATEGORY],
            )
        )
        derived: dict[str, _Derived] = {}
        for iri in chunk:
            values = literals.get(iri, {})
            kind = kind_of(types.get(iri, set()), timestamped=GENERATED_AT in values)
            own = next((values[p] for p in TIMES if p in values), None)
            derived[iri] = _Derived(kind, _normal_time(own), display_label(iri, kind, values, categories.get(iri)))
        borrowing = [iri for iri, d in derived.items() if d.time is None and d.kind in ("message", "emotion")]
        for iri, time in _borrowed_times(connection, borrowing).items():
            derived[iri].time = time
        connection.executemany(
            "INSERT OR REPLACE INTO graph_nodes VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            [
                (iri, d.kind, RANK[d.kind], d.time, instant_of(d.time) if d.time else UNTIMED, d.label,
                 f"{d.label.casefold()}\n{iri.casefold()}", json.dumps(sorted(compact(t) for t in types.get(iri, ()))))
                for iri, d in derived.items()
            ],
        )  # fmt: skip


def _borrowed_times(connection: Any, iris: list[str]) -> dict[str, str]:
    """The time of the activity behind each message or emotion: the activity that generated it, else what
    produced it (an activity, or an annotation and the activity that produced that)."""
    found: dict[str, str] = {}
    routes = [
        # the message -wasGeneratedBy-> activity
        "SELECT l.source, t.predicate, t.value FROM graph_links l JOIN graph_literals t ON t.iri = l.target "
        "WHERE l.predicate = ? AND l.source IN ({marks}) AND t.predicate IN (?, ?, ?)",
        # activity -producedEntityResult|hasEmotion-> it
        "SELECT l.target, t.predicate, t.value FROM graph_links l JOIN graph_literals t ON t.iri = l.source "
        "WHERE l.predicate IN (?, ?) AND l.target IN ({marks}) AND t.predicate IN (?, ?, ?)",
        # activity -producedEntityResult-> annotation -hasEmotion-> it
        "SELECT l2.target, t.predicate, t.value FROM graph_links l2 JOIN graph_links l1 ON l1.target = l2.source "
        "AND l1.predicate IN (?, ?) JOIN graph_literals t ON t.iri = l1.source "
        "WHERE l2.predicate IN (?, ?) AND l2.target IN ({marks}) AND t.predicate IN (?, ?, ?)",
    ]
    for chunk in _chunks(iris):
        marks = ", ".join("?" * len(chunk))
        arguments = [
            [WAS_GENERATED_BY, *chunk, *TIMES],
            [PRODUCED, HAS_EMOTION, *chunk, *TIMES],
            [PRODUCED, HAS_EMOTION, PRODUCED, HAS_EMOTION, *chunk, *TIMES],
        ]
        for route, route_arguments in zip(routes, arguments, strict=True):
            best: dict[str, tuple[int, str]] = {}
            for iri, predicate, value in connection.execute(route.format(marks=marks), route_arguments):
                if iri in found:
                    continue
                time = _normal_time(value)
                preference = TIMES.index(predicate)
                if time and (iri not in best or (preference, time) < best[iri]):
                    best[iri] = (preference, time)
            found.update({iri: time for iri, (_, time) in best.items()})
    return found


def display_label(iri: str, kind: Kind, literals: dict[str, str], category: str | None) -> str:
    """A name for a node: its own name, an emotion's category and intensity, its text, or its IRI's end."""
    for predicate in LABELS:
        if predicate in literals:
            return literals[predicate]
    if kind == "emotion" and INTENSITY in literals:
        name = local_name(category).removeprefix("big6_") if category else ""
        return f"{name} {literals[INTENSITY]}".strip()
    for predicate in (TEXT, DESCRIPTION):
        if predicate in literals:
            text = literals[predicate]
            return text if len(text) <= MAX_LABEL else text[: MAX_LABEL - 1] + "…"
    return local_name(iri)


def _node(iri: str, kind: str, time: str | None, label: str, types: str) -> dict[str, object]:
    node: dict[str, object] = {"id": iri, "label": label, "kind": kind, "types": list(_types(types))}
    if time:
        node["time"] = time
    return node


@lru_cache(maxsize=4096)
def _types(listed: str) -> tuple[str, ...]:
    """A node's stored type list, parsed once: a graph of thousands of nodes has a few dozen distinct lists."""
    return tuple(json.loads(listed))


def _total(connection: Any, query: _CandidateQuery) -> int:
    """How many nodes the request allows: kept as a count for the unfiltered view, counted otherwise."""
    if query.unfiltered:
        return int(connection.execute("SELECT nodes FROM graph_state").fetchone()[0])
    return int(connection.execute(*query.count()).fetchone()[0])


def _edges(connection: Any, iris: list[str]) -> list[dict[str, str]]:
    """The links between drawn nodes. The client doubles most links with a PROV copy
    (segb:wasPerformedBy + prov:wasAssociatedWith, schema:sender + prov:wasAttributedTo, ...); drawing both
    only doubles every arrow."""
    listed = json.dumps(iris)
    links = connection.execute(
        "SELECT source, predicate, target FROM graph_links WHERE source IN (SELECT value FROM json_each(?)) "
        "AND target IN (SELECT value FROM json_each(?)) ORDER BY source, predicate, target",
        (listed, listed),
    ).fetchall()
    primary_pairs = {(s, o) for s, p, o in links if not p.startswith(PROV)}
    labels = {p: local_name(p) for p in {p for _, p, _ in links}}  # a few predicates label thousands of links
    return [
        {"id": f"{s} {p} {o}", "source": s, "target": o, "predicate": p, "label": labels[p]}
        for s, p, o in links
        if not (p.startswith(PROV) and (s, o) in primary_pairs)
    ]


def _matches(node: dict[str, object], needle: str) -> bool:
    return needle in str(node["label"]).casefold() or needle in str(node["id"]).casefold()


# The first view's nodes are the first rows of graph_nodes in this order (`_CandidateQuery` with no filter).
_FIRST_VIEW_ORDER = "ORDER BY rank, instant, iri"
_NODE_COLUMNS = "iri, rank, instant, kind, time, label, types"  # the sort key first


def _first_view_cutoff(connection: Any) -> tuple[Any, ...] | None:
    """The sort key of the last row the first view reads (its limit and one more, which tells whether it is cut
    off); None while there are fewer nodes, when every node is in it."""
    return connection.execute(
        f"SELECT rank, instant, iri FROM graph_nodes {_FIRST_VIEW_ORDER} LIMIT 1 OFFSET ?", (FIRST_VIEW.limit,)
    ).fetchone()


def _node_rows(connection: Any, iris: Iterable[str]) -> dict[str, tuple[Any, ...]]:
    rows: dict[str, tuple[Any, ...]] = {}
    for chunk in _chunks(sorted(iris)):
        marks = ", ".join("?" * len(chunk))
        for row in connection.execute(f"SELECT {_NODE_COLUMNS} FROM graph_nodes WHERE iri IN ({marks})", chunk):
            rows[row[0]] = row
    return rows


def _first_view_changed(
    cutoff: tuple[Any, ...] | None,
    before: dict[str, tuple[Any, ...]],
    after: dict[str, tuple[Any, ...]],
    links: list[tuple[str, str, str]],
) -> bool:
    """Whether the first view draws something else now that the nodes in `after` (every node written) were
    `before` (absent: new) and `links` were added. Only a node written inside the view's rows, before or after,
    changes them; when none did, the view's rows are those up to `cutoff` as before, and a new link changes it
    when both its ends are among them."""

    def drawn(row: tuple[Any, ...] | None) -> bool:
        return row is not None and (cutoff is None or (row[1], row[2], row[0]) <= cutoff)

    for iri, row in after.items():
        old = before.get(iri)
        if row != old and (drawn(old) or drawn(row)):
            return True
    return any(drawn(after.get(source)) and drawn(after.get(target)) for source, _, target in links)


def _subjects_and_targets(quads: Iterable[Quad]) -> set[str]:
    """The IRIs `_store_facts` may add as nodes: named subjects and named objects."""
    return {term.value for quad in quads for term in (quad.subject, quad.object) if isinstance(term, NamedNode)}


def _new_first_view(connection: Any) -> None:
    """A first view unlike any kept one (after a build or a clearing, which start the counter again)."""
    connection.execute("UPDATE graph_state SET first_view = ?", (time_ns(),))


def _record_changes(connection: Any, iris: Sequence[str], through: int) -> None:
    """Log the nodes step `through` wrote, for kept neighbourhoods, and forget the steps past what the log keeps."""
    connection.executemany("INSERT INTO graph_changes VALUES (?, ?)", [(through, iri) for iri in iris])
    oldest = through - CHANGES_KEPT_STEPS
    if connection.execute("SELECT 1 FROM graph_changes WHERE seq <= ? LIMIT 1", (oldest,)).fetchone():
        connection.execute("DELETE FROM graph_changes WHERE seq <= ?", (oldest,))
        connection.execute("UPDATE graph_state SET changes_from = MAX(changes_from, ?)", (oldest,))


def _set_through(connection: Any, through: int, *, changed: bool) -> None:
    connection.execute(
        "INSERT INTO graph_state (id, version, through, changed) VALUES (1, ?, ?, ?) ON CONFLICT (id) DO UPDATE SET "
        "version = excluded.version, through = excluded.through, changed = CASE WHEN ? THEN excluded.through "
        "ELSE changed END",
        (STORED_VERSION, through, through, changed),
    )


def _expanded(value: str) -> str:
    """A class CURIE as its IRI (an IRI stays as it is)."""
    prefix, _, rest = value.partition(":")
    return PREFIXES[prefix] + rest if prefix in PREFIXES and not rest.startswith("//") else value


def _chunks(items: Sequence[str]) -> Iterator[Sequence[str]]:
    for start in range(0, len(items), CHUNK):
        yield items[start : start + CHUNK]


def _normal_time(value: str | None) -> str | None:
    if value is None:
        return None
    try:
        return iso_time(value)
    except ValueError:
        return None


def instant_of(iso: str) -> str:
    """A time as fixed-width UTC text, which sorts as the instants do: `…05.25Z` is after `…05Z` although
    `.` sorts before `Z`."""
    moment = datetime.fromisoformat(iso.replace("Z", "+00:00"))
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return moment.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def local_name(iri: str) -> str:
    return iri.rstrip("/#").replace("#", "/").rsplit("/", 1)[-1] or iri
