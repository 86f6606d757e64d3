"""One SQL query choosing the nodes a graph request draws: each filter adds a common table expression of the node
ids it allows and a condition on the node; a focus adds the distances from it (recursive)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from segb_server.backend.services.graph.facts import RANK, UNTIMED, instant_of
from segb_server.backend.vocabulary import KINDS, PERFORMED_BY, PREFIXES

ATTRIBUTED_TO = PREFIXES["prov"] + "wasAttributedTo"
NOWHERE = -1  # the id of an IRI the index does not hold: matches no node
ALL_RANKS = ", ".join(str(RANK[kind]) for kind in KINDS)


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

    def iris(self) -> set[str]:
        """The IRIs the request names, whose ids its query needs."""
        return {PERFORMED_BY, ATTRIBUTED_TO} | {iri for iri in (self.robot, self.focus) if iri}


FIRST_VIEW = GraphRequest()  # the kg-graph's first view: no filter, the default limit
# The nodes a view draws, each as `node_of` takes them: the sort key and the id first.
NODE_COLUMNS = "n.rank, n.instant, n.tie, n.id, t.text, n.time, n.label, s.types"
NODE_FROM = "graph_nodes n JOIN graph_terms t ON t.id = n.id JOIN graph_typesets s ON s.id = n.typeset"


class CandidateQuery:
    def __init__(self, request: GraphRequest, ids: Mapping[str, int]) -> None:
        """`ids`: the ids of `request.iris()` the index holds."""
        self.ctes: list[str] = []
        self.arguments: list[object] = []
        self.conditions: list[str] = []
        self.condition_arguments: list[object] = []
        self.distance = False
        self.searched = False
        self._ids = ids
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

    def _id(self, iri: str) -> int:
        return self._ids.get(iri, NOWHERE)

    def _cte(self, text: str, *arguments: object) -> None:
        self.ctes.append(text)
        self.arguments.extend(arguments)

    def _robot(self, robot: str) -> None:
        """The robot, what it did and was attributed (activities, states), what those touched, and the
        emotions and humans one step further (through annotations and shared events)."""
        self._cte(
            "robot_seeds(id) AS (SELECT ? UNION SELECT source FROM graph_links WHERE target = ? "
            "AND predicate IN (?, ?))",
            self._id(robot), self._id(robot), self._id(PERFORMED_BY), self._id(ATTRIBUTED_TO),
        )  # fmt: skip
        self._cte(
            "robot_around(id) AS (SELECT id FROM robot_seeds "
            "UNION SELECT l.target FROM robot_seeds s JOIN graph_links l ON l.source = s.id "
            "UNION SELECT l.source FROM robot_seeds s JOIN graph_links l ON l.target = s.id)"
        )
        self._cte(
            "robot_set(id) AS (SELECT id FROM robot_around UNION SELECT l.target FROM robot_around a "
            "JOIN graph_nodes n ON n.id = a.id AND n.rank IN (?, ?) "
            "JOIN graph_links l ON l.source = a.id)",
            RANK["emotion"], RANK["shared-event"],
        )  # fmt: skip
        self.conditions.append("n.id IN robot_set")

    def _window(self, since: str | None, until: str | None) -> None:
        """Timed nodes inside the window, and untimed nodes linked to one of them."""
        # Every kind named, so the window is a range of instants within each kind's part of the drawing
        # order's index: the nodes need no index of their instants of their own.
        bounds, arguments = [f"rank IN ({ALL_RANKS})", f"instant < {UNTIMED}"], []
        if since:
            bounds.append("instant >= ?")
            arguments.append(instant_of(since))
        if until:
            bounds.append("instant <= ?")
            arguments.append(instant_of(until))
        self._cte(f"window_timed(id) AS (SELECT id FROM graph_nodes WHERE {' AND '.join(bounds)})", *arguments)
        self._cte(
            "window_set(id) AS (SELECT id FROM window_timed "
            "UNION SELECT l.target FROM window_timed t JOIN graph_links l ON l.source = t.id "
            f"JOIN graph_nodes u ON u.id = l.target AND u.instant = {UNTIMED} "
            "UNION SELECT l.source FROM window_timed t JOIN graph_links l ON l.target = t.id "
            f"JOIN graph_nodes u ON u.id = l.source AND u.instant = {UNTIMED})"
        )
        self.conditions.append("n.id IN window_set")

    def _types(self, wanted: Sequence[str]) -> None:
        """Kinds (`robot`), class CURIEs (`oro:Robot`) or class IRIs."""
        ranks = [RANK[value] for value in wanted if value in KINDS]
        classes = sorted({_expanded(value) for value in wanted if value not in KINDS})
        either = []
        if ranks:
            either.append(f"n.rank IN ({', '.join('?' * len(ranks))})")
            self.condition_arguments.extend(ranks)
        if classes:
            either.append(
                "n.typeset IN (SELECT ts.id FROM graph_typesets ts, json_each(ts.types) c "
                f"WHERE c.value IN ({', '.join('?' * len(classes))}))"
            )
            self.condition_arguments.extend(classes)
        self.conditions.append(f"({' OR '.join(either)})")

    def _search(self, needle: str) -> None:
        """Nodes whose label or IRI holds the text (any case), among the nodes allowed so far, and their
        neighbours."""
        where = " AND ".join(
            [*self.conditions, "(instr(COALESCE(n.folded, lower(n.label)), ?) > 0 OR instr(lower(t.text), ?) > 0)"]
        )
        self._cte(
            f"hits(id) AS (SELECT n.id FROM {NODE_FROM} WHERE {where})", *self.condition_arguments, needle, needle
        )
        self._cte(
            "hit_set(id) AS (SELECT id FROM hits "
            "UNION SELECT l.target FROM hits h JOIN graph_links l ON l.source = h.id "
            "UNION SELECT l.source FROM hits h JOIN graph_links l ON l.target = h.id)"
        )
        self.conditions.append("n.id IN hit_set")
        self.searched = True

    def _focus(self, focus: str, depth: int) -> None:
        self._cte(
            "reach(id, d) AS (SELECT ?, 0 "
            "UNION SELECT l.target, r.d + 1 FROM reach r JOIN graph_links l ON l.source = r.id WHERE r.d < ? "
            "UNION SELECT l.source, r.d + 1 FROM reach r JOIN graph_links l ON l.target = r.id WHERE r.d < ?)",
            self._id(focus), depth, depth,
        )  # fmt: skip
        self._cte("distance(id, d) AS (SELECT id, MIN(d) FROM reach GROUP BY id)")
        self.distance = True

    def _select(self, columns: str) -> tuple[str, list[object]]:
        head = f"WITH RECURSIVE {', '.join(self.ctes)} " if self.ctes else ""
        join = " JOIN distance d ON d.id = n.id" if self.distance else ""
        where = f" WHERE {' AND '.join(self.conditions)}" if self.conditions else ""
        return f"{head}SELECT {columns} FROM {NODE_FROM}{join}{where}", [*self.arguments, *self.condition_arguments]

    @property
    def unfiltered(self) -> bool:
        return not self.ctes and not self.conditions

    def ordered(self, limit: int) -> tuple[str, list[object]]:
        """The nodes drawn, in drawing order, each as `node_of` takes them."""
        text, arguments = self._select(NODE_COLUMNS)
        order = "d.d, n.rank, n.instant, n.tie, n.id" if self.distance else "n.rank, n.instant, n.tie, n.id"
        if self.searched:  # what was searched for first, then its neighbours: a limit must not cut the hits
            order = "n.id NOT IN hits, " + order
        return f"{text} ORDER BY {order} LIMIT ?", [*arguments, limit]

    def count(self) -> tuple[str, list[object]]:
        return self._select("COUNT(*)")

    def reached(self) -> tuple[str, list[object]]:
        """Every node within a focus request's depth, whatever its other filters."""
        assert self.distance, "only a request with a focus reaches nodes"
        return f"WITH RECURSIVE {', '.join(self.ctes)} SELECT id FROM distance", list(self.arguments)


def _expanded(value: str) -> str:
    """A class CURIE as its IRI (an IRI stays as it is)."""
    prefix, _, rest = value.partition(":")
    return PREFIXES[prefix] + rest if prefix in PREFIXES and not rest.startswith("//") else value
