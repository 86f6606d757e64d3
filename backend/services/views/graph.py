"""The knowledge graph as nodes and edges for drawing, and everything about one resource.

`GET /graph` loads the drawable part of the events graph with one query (`sparql/graph/elements.rq`), then
filters here: by robot, time window, kind or class, label search, and the neighbourhood of a focus node.
Literals only name and place nodes; the rest are details fetched per node (`resource`).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Collection, Iterable
from dataclasses import dataclass, field
from datetime import datetime

from pyoxigraph import Literal, NamedNode

from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.ops.result_cache import DataVersion, ResultCache
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, Catalog, paged
from segb_server.backend.services.views.term_values import iso_time, json_value
from segb_server.backend.store.base import Store, Term, select
from segb_server.backend.store.terms import bind_rows
from segb_server.backend.vocabulary import KINDS, PREFIXES, Kind, compact, kind_of

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
MAX_LABEL = 60
MAX_NODES = 20_000
INCOMING_LIMIT = 500  # statements pointing at one resource, read at once


@dataclass
class Node:
    id: str
    types: set[str] = field(default_factory=set)
    labels: dict[str, str] = field(default_factory=dict)
    times: dict[str, str] = field(default_factory=dict)
    kind: Kind = "other"
    time: str | None = None

    @property
    def label(self) -> str:
        for predicate in LABELS:
            if predicate in self.labels:
                return self.labels[predicate]
        for predicate in (TEXT, DESCRIPTION):
            if predicate in self.labels:
                text = self.labels[predicate]
                return text if len(text) <= MAX_LABEL else text[: MAX_LABEL - 1] + "…"
        return local_name(self.id)

    def as_json(self) -> dict[str, object]:
        body: dict[str, object] = {
            "id": self.id,
            "label": self.label,
            "kind": self.kind,
            "types": sorted(compact(t) for t in self.types),
        }
        if self.time:
            body["time"] = self.time
        return body


def local_name(iri: str) -> str:
    return iri.rstrip("/#").replace("#", "/").rsplit("/", 1)[-1] or iri


@dataclass(frozen=True)
class Edge:
    source: str
    predicate: str
    target: str

    def as_json(self) -> dict[str, str]:
        return {
            "id": f"{self.source} {self.predicate} {self.target}",
            "source": self.source,
            "target": self.target,
            "predicate": self.predicate,
            "label": local_name(self.predicate),
        }


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


class KnowledgeGraph:
    """The drawable graph in memory: nodes by IRI and edges with adjacency both ways."""

    def __init__(self) -> None:
        self.nodes: dict[str, Node] = {}
        self.edges: list[Edge] = []
        self.out: dict[str, list[Edge]] = {}
        self.into: dict[str, list[Edge]] = {}

    def node(self, iri: str) -> Node:
        found = self.nodes.get(iri)
        if found is None:
            found = self.nodes[iri] = Node(iri)
        return found

    def neighbours(self, iri: str) -> Iterable[str]:
        for edge in self.out.get(iri, ()):
            yield edge.target
        for edge in self.into.get(iri, ()):
            yield edge.source

    @classmethod
    def from_triples(cls, triples: Iterable[tuple[str, str, Term]]) -> KnowledgeGraph:
        graph = cls()
        links: set[tuple[str, str, str]] = set()
        for subject, predicate, value in triples:
            node = graph.node(subject)
            if isinstance(value, Literal):
                if predicate in TIMES:
                    node.times[predicate] = value.value
                else:
                    node.labels.setdefault(predicate, value.value)
            elif predicate == RDF_TYPE:
                node.types.add(value.value)
            else:
                graph.node(value.value)
                links.add((subject, predicate, value.value))
        graph._add_links(links)
        graph._classify()
        return graph

    def _add_links(self, links: set[tuple[str, str, str]]) -> None:
        # The client doubles most links with a PROV copy (segb:wasPerformedBy + prov:wasAssociatedWith,
        # schema:sender + prov:wasAttributedTo, ...); drawing both only doubles every arrow.
        primary_pairs = {(s, o) for s, p, o in links if not p.startswith(PROV)}
        for subject, predicate, target in sorted(links):
            if predicate.startswith(PROV) and (subject, target) in primary_pairs:
                continue
            edge = Edge(subject, predicate, target)
            self.edges.append(edge)
            self.out.setdefault(subject, []).append(edge)
            self.into.setdefault(target, []).append(edge)

    def _classify(self) -> None:
        for node in self.nodes.values():
            node.kind = kind_of(node.types, timestamped=GENERATED_AT in node.times)
            own = next((node.times[p] for p in TIMES if p in node.times), None)
            node.time = _normal_time(own)
            if node.kind == "emotion" and INTENSITY in node.labels:
                category = next(
                    (local_name(e.target) for e in self.out.get(node.id, ()) if e.predicate == CATEGORY), ""
                )
                node.labels.setdefault(LABELS[-1], f"{category.removeprefix('big6_')} {node.labels[INTENSITY]}".strip())
        # Messages, annotations and their emotions happen when the activity behind them does.
        for node in self.nodes.values():
            if node.time is None and node.kind in ("message", "emotion"):
                node.time = self._borrowed_time(node.id)

    def _borrowed_time(self, iri: str, hops: int = 2) -> str | None:
        for edge in self.out.get(iri, ()):
            if edge.predicate == WAS_GENERATED_BY and self.nodes[edge.target].time:
                return self.nodes[edge.target].time
        for edge in self.into.get(iri, ()):
            if edge.predicate in (PRODUCED, HAS_EMOTION):
                source = self.nodes[edge.source]
                if source.time:
                    return source.time
                if hops > 1:
                    borrowed = self._borrowed_time(source.id, hops - 1)
                    if borrowed:
                        return borrowed
        return None


def _normal_time(value: str | None) -> str | None:
    if value is None:
        return None
    try:
        return iso_time(value)
    except ValueError:
        return None


class GraphService:
    def __init__(self, catalog: Catalog, store: Store, cache: ResultCache | None = None) -> None:
        self.catalog = catalog
        self.store = store
        self.cache = cache or ResultCache(DataVersion(), enabled=False)

    def load(self) -> KnowledgeGraph:
        return self.cache.get(("graph",), self._load)

    def _load(self) -> KnowledgeGraph:
        query = self.catalog.get("graph/elements")
        rows = select(self.store, query.text).rows
        return KnowledgeGraph.from_triples(
            (row["subject"].value, row["predicate"].value, row["object"]) for row in rows
        )

    def graph(self, request: GraphRequest) -> dict[str, object]:
        """The nodes and edges to draw; blocking (store I/O)."""
        graph = self.load()
        chosen = select_nodes(graph, request)
        truncated = len(chosen) > request.limit
        kept = chosen[: request.limit]
        kept_ids = set(kept)
        edges = [e.as_json() for e in graph.edges if e.source in kept_ids and e.target in kept_ids]
        matches = [iri for iri in kept if request.q and _matches(graph.nodes[iri], request.q)]
        return {
            "nodes": [graph.nodes[iri].as_json() for iri in kept],
            "edges": edges,
            "truncated": truncated,
            "total_nodes": len(chosen),
            "matches": matches,
        }

    def resource(
        self, iri: str, *, incoming: Collection[str] | None = None, incoming_limit: int = INCOMING_LIMIT
    ) -> dict[str, object]:
        """Every triple from one resource and up to `incoming_limit` pointing at it (only those with the
        `incoming` predicates when given), with labels; blocking (store I/O). A robot after a month of logs is
        the object of hundreds of thousands of triples: `incoming_truncated` says when some were left out."""
        outgoing = self._statements("graph/resource-out", iri)
        query = self.catalog.get("graph/resource-in")
        text, bindings = query.text, query.bindings({"iri": iri})
        if incoming is not None:  # one VALUES row per (resource, predicate) instead of the resource alone
            rows: list[list[Term | None]] = [[NamedNode(iri), NamedNode(p)] for p in sorted(incoming)]
            text, bindings = bind_rows(text, [PARAMETER_VARIABLE_PREFIX + "iri", "predicate"], rows), {}
        found = self._statements_of(select(self.store, paged(text, incoming_limit + 1, None), bindings).rows)
        truncated = len(found) > incoming_limit
        incoming_statements = sorted(found[:incoming_limit], key=lambda s: (s["predicate"], str(s["value"])))
        node = Node(iri)
        for statement in outgoing:
            predicate, value = str(statement["predicate"]), str(statement["value"])
            if predicate == RDF_TYPE:
                node.types.add(value)
            elif predicate in TIMES:
                node.times[predicate] = value
            elif statement["is_literal"]:
                node.labels.setdefault(predicate, value)
        node.kind = kind_of(node.types, timestamped=GENERATED_AT in node.times)
        node.time = next((node.times[p] for p in TIMES if p in node.times), None)
        return {
            **node.as_json(),
            "iri": iri,
            "outgoing": outgoing,
            "incoming": incoming_statements,
            "incoming_truncated": truncated,
        }

    def _statements(self, query_name: str, iri: str) -> list[dict[str, object]]:
        query = self.catalog.get(query_name)
        return self._statements_of(select(self.store, query.text, query.bindings({"iri": iri})).rows)

    def _statements_of(self, rows: list[dict[str, Term]]) -> list[dict[str, object]]:
        statements = []
        for row in rows:
            value = row["value"]
            statement: dict[str, object] = {
                "predicate": row["predicate"].value,
                "predicate_label": compact(row["predicate"].value),
                "value": json_value(value),
                "is_literal": isinstance(value, Literal),
            }
            if isinstance(value, Literal):
                statement["datatype"] = compact(value.datatype.value)
                if value.language:
                    statement["language"] = value.language
            elif "valueLabel" in row:
                statement["label"] = row["valueLabel"].value
            else:
                statement["label"] = local_name(value.value) if isinstance(value, NamedNode) else str(json_value(value))
            statements.append(statement)
        return statements


def _of_type(node: Node, wanted: set[str]) -> bool:
    """`wanted` holds kinds (`robot`), class CURIEs (`oro:Robot`) or class IRIs."""
    return node.kind in wanted or any(t in wanted or compact(t) in wanted for t in node.types)


def _matches(node: Node, needle: str) -> bool:
    folded = needle.casefold()
    return folded in node.label.casefold() or folded in node.id.casefold()


def select_nodes(graph: KnowledgeGraph, request: GraphRequest) -> list[str]:
    """The IRIs of the nodes to draw, most relevant first (the caller cuts at the limit)."""
    candidates = set(graph.nodes)
    if request.robot:
        candidates &= robot_neighbourhood(graph, request.robot)
    if request.since or request.until:
        candidates &= in_time_window(graph, request.since, request.until)
    if request.types:
        wanted = set(request.types)
        candidates = {iri for iri in candidates if _of_type(graph.nodes[iri], wanted)}
    if request.q:
        hits = {iri for iri in candidates if _matches(graph.nodes[iri], request.q)}
        candidates &= hits | {n for iri in hits for n in graph.neighbours(iri)}
    distance: dict[str, int] = {}
    if request.focus:
        if request.focus not in graph.nodes:
            return []
        distance = breadth_first(graph, request.focus, request.depth)
        candidates &= set(distance)
    rank = {kind: i for i, kind in enumerate(KINDS)}

    def order(iri: str) -> tuple[int, int, str, str]:
        node = graph.nodes[iri]
        return distance.get(iri, 0), rank[node.kind], node.time or "~", iri

    return sorted(candidates, key=order)


def breadth_first(graph: KnowledgeGraph, start: str, depth: int) -> dict[str, int]:
    seen = {start: 0}
    queue = deque([start])
    while queue:
        current = queue.popleft()
        if seen[current] >= depth:
            continue
        for neighbour in graph.neighbours(current):
            if neighbour not in seen:
                seen[neighbour] = seen[current] + 1
                queue.append(neighbour)
    return seen


def robot_neighbourhood(graph: KnowledgeGraph, robot: str) -> set[str]:
    """The robot, what it did and was attributed (activities, states), what those touched, and the
    emotions and humans one step further (through annotations and shared events)."""
    seeds = {robot} | {e.source for e in graph.into.get(robot, ()) if e.predicate in (PERFORMED_BY, ATTRIBUTED_TO)}
    around = seeds | {n for iri in seeds for n in graph.neighbours(iri)}
    further = {
        e.target
        for iri in around
        if graph.nodes[iri].kind in ("emotion", "shared-event")
        for e in graph.out.get(iri, ())
    }
    return around | further


def in_time_window(graph: KnowledgeGraph, since: str | None, until: str | None) -> set[str]:
    """Timed nodes inside the window, and untimed nodes linked to one of them. Times are compared as
    instants, not strings: `…05.25Z` is after `…05Z` although `.` sorts before `Z`."""
    start = _instant(since) if since else None
    end = _instant(until) if until else None
    timed = set()
    for iri, node in graph.nodes.items():
        if node.time:
            moment = _instant(node.time)
            if (start is None or moment >= start) and (end is None or moment <= end):
                timed.add(iri)
    untimed = {n for iri in timed for n in graph.neighbours(iri) if graph.nodes[n].time is None}
    return timed | untimed


def _instant(iso: str) -> datetime:
    return datetime.fromisoformat(iso.replace("Z", "+00:00"))


def parse_types(raw: str | None) -> tuple[str, ...]:
    if not raw:
        return ()
    values = tuple(part.strip() for part in raw.split(",") if part.strip())
    for value in values:
        if value not in KINDS and ":" not in value:
            raise InvalidParameter("types", f"'{value}' is neither a kind ({', '.join(KINDS)}) nor a class IRI/CURIE")
    return values
