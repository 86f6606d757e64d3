"""A SHACL rule checked one focus node's own statements at a time: compiled (shape_check.py) when its shapes
are simple enough, else with pySHACL.

Both check the nodes they are given (pySHACL with `focus_nodes` and `use_shapes`: no target search of its own),
against those nodes' statements read from the store: the predicates the shapes' paths name, or every
statement of the node when a shape reads more (a path of several steps, a SPARQL constraint). So a shape sees
exactly what a node says of itself, whatever the store (the embedded one or Virtuoso), and checking a node
costs what that node holds, not the size of the log. Which nodes are a shape's targets is asked of the store
from the shape's own target declarations (`sh:targetClass`, `sh:targetNode`, `sh:targetSubjectsOf`,
`sh:targetObjectsOf`, and a SPARQL-based `sh:target` whose select binds `?this`), for the nodes a batch of new
triples names or, for a full check, for all.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import cached_property

import pyshacl
from pyoxigraph import NamedNode
from rdflib import RDF, SH, BNode, Graph, URIRef
from rdflib.term import Literal as RdfLiteral
from rdflib.term import Node

from segb_server.backend.reading import TIME_PREDICATES
from segb_server.backend.services.rules.catalog import Rule
from segb_server.backend.services.rules.shape_check import PropertyCheck, as_rdflib, check_node, compile_shape
from segb_server.backend.services.sparql.parser import exclusive
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.sparql_text import top_level_where, top_level_where_end
from segb_server.backend.store.terms import bind_rows, term_text
from segb_server.backend.vocabulary import PERFORMED_BY, PREFIXES

NODES_PER_QUERY = 300
FOCUS_PER_RUN = 200
PROV = PREFIXES["prov"]
# What a finding lists besides the shape's message, read from the focus node's own statements.
TIMES = TIME_PREDICATES
# Its robot: the one that performed it; or the agent it is attributed to, unless it is something said (the PyPI
# client attributes a message to its sender, a person as often as not); or, for what an activity generated (a
# message, an observation), the robot that performed that activity (`robots_of_generating`).
ATTRIBUTED_TO, GENERATED_BY = PROV + "wasAttributedTo", PROV + "wasGeneratedBy"
SENDER, MESSAGE = PREFIXES["schema"] + "sender", PREFIXES["schema"] + "Message"
ACTORS = (PERFORMED_BY, ATTRIBUTED_TO, SENDER, GENERATED_BY)
XSD_DATETIME = PREFIXES["xsd"] + "dateTime"
RDF_TYPE = str(RDF.type)


@dataclass(frozen=True)
class ShapeResult:
    """One validation result: its focus node (N-Triples text), message, and the path and value it names."""

    focus: str
    message: str
    path: str | None
    value: str | None


@dataclass(frozen=True)
class Context:
    """What the findings page lists about a focus node, from its own statements: its time and its robot (or the
    activity that generated it, whose robot is then its own)."""

    time: object | None = None  # a pyoxigraph term (a literal xsd:dateTime)
    robot: object | None = None  # a pyoxigraph term (an IRI)
    generated_by: str | None = None  # N-Triples text of an IRI

    @classmethod
    def of(cls, noted: dict[str, object]) -> Context:
        said = bool(noted.get("said"))
        robot = noted.get("performer") or (None if said else noted.get("attributed"))
        generated_by = noted.get("generated_by")
        return cls(noted.get("time"), robot, term_text(generated_by) if isinstance(generated_by, NamedNode) else None)


class NodeStatements:
    """Statements read of some nodes, by node (N-Triples text) and predicate (IRI), as the store's terms; as an
    rdflib graph too, made only when pySHACL checks a shape that does not compile."""

    def __init__(self) -> None:
        self.by_node: dict[str, dict[str, list[object]]] = {}

    def add(self, node: str, predicate: str, value: object) -> None:
        self.by_node.setdefault(node, {}).setdefault(predicate, []).append(value)

    def values(self, node: str) -> dict[str, list[object]]:
        return self.by_node.get(node, {})

    def says(self, node: str, predicate: str, value: object | None = None) -> bool:
        """Whether the node is the subject of a statement with this predicate (and this object, if given)."""
        values = self.values(node).get(predicate)
        return bool(values) and (value is None or value in values)  # type: ignore[operator]

    @cached_property
    def graph(self) -> Graph:
        graph = Graph()
        for node, predicates in self.by_node.items():
            subject = URIRef(node[1:-1])
            for predicate, values in predicates.items():
                for value in values:
                    graph.add((subject, URIRef(predicate), as_rdflib(value)))
        return graph


class ShapeRule:
    """One shapes file: its node shapes, their targets, and what a check of some nodes reads."""

    def __init__(self, rule: Rule, *, compiled: bool = True) -> None:
        """`compiled`: the shapes that compile are checked without pySHACL (False: every shape with pySHACL)."""
        assert rule.shapes is not None
        self.rule = rule
        self.graph = Graph().parse(data=rule.shapes, format="turtle")
        self.shapes = sorted({s for s in self.graph.subjects(RDF.type, SH.NodeShape) if isinstance(s, URIRef)}, key=str)
        # Each shape's property checks, when it compiles (shape_check.py); None: pySHACL checks it.
        self.checks: dict[URIRef, list[PropertyCheck] | None] = {
            shape: compile_shape(self.graph, shape) if compiled else None for shape in self.shapes
        }
        self._targets = {shape: _target_queries(self.graph, shape) for shape in self.shapes}
        # Targets a node's own statements tell (its type, the predicates it is the subject of, its IRI): read from
        # them when a batch's nodes are checked, instead of a store query each.
        self._own = {shape: _own_targets(self.graph, shape) for shape in self.shapes}
        self.predicates = _read_predicates(self.graph)  # None: every statement of a focus node

    # --- targets -------------------------------------------------------------------------------------

    def targets(self, store: Store, candidates: Iterable[str] | None) -> dict[URIRef, set[str]]:
        """Each shape's targets (N-Triples texts of IRIs) among `candidates`, or all of them (None)."""
        listed = None if candidates is None else sorted({c for c in candidates if c.startswith("<")})
        found: dict[URIRef, set[str]] = {shape: set() for shape in self.shapes}
        for shape, queries in self._targets.items():
            for query in queries:
                for chunk in [None] if listed is None else _chunks(listed):
                    found[shape].update(_ask_targets(store, query, chunk))
        return found

    def targets_among(
        self, store: Store, candidates: list[str], data: NodeStatements, delta: Delta | None = None
    ) -> dict[URIRef, set[str]]:
        """Each shape's targets among `candidates` (N-Triples texts of IRIs) whose statements `data` holds: the
        targets their own statements tell, from them; the objects of a predicate, from `delta` for the batch's
        fresh nodes (every triple naming them is the batch's); the others from the store."""
        found: dict[URIRef, set[str]] = {shape: set() for shape in self.shapes}
        for shape, (nodes, classes, predicates, asked) in self._own.items():
            found[shape].update(node for node in candidates if node in nodes)
            types = [NamedNode(str(cls)) for cls in classes]
            for node in candidates:
                if any(data.says(node, RDF_TYPE, cls) for cls in types) or any(
                    data.says(node, str(predicate)) for predicate in predicates
                ):
                    found[shape].add(node)
            for target in asked:
                remaining = candidates
                if delta is not None and target.predicate is not None:
                    predicate = target.predicate
                    found[shape].update(
                        node for node in candidates if node in delta.fresh and delta.with_predicate(predicate, node)
                    )
                    remaining = [node for node in candidates if node not in delta.fresh]
                for chunk in _chunks(remaining):
                    found[shape].update(_ask_targets(store, target.query, chunk))
        return found

    def statement_predicates(self) -> frozenset[str] | None:
        """What finding this rule's targets and checking them reads of a node (None: every statement)."""
        if self.predicates is None:
            return None
        told = {str(p) for own in self._own.values() for p in own[2]}
        return self.predicates | told | {str(RDF.type)}

    # --- checking ------------------------------------------------------------------------------------

    def check(self, store: Store, targets: dict[URIRef, set[str]]) -> tuple[list[ShapeResult], dict[str, Context]]:
        """Validate each shape on its targets; the results and each checked node's context."""
        nodes = sorted(set().union(*targets.values())) if targets else []
        if not nodes:
            return [], {}
        data, contexts = statements(store, nodes, self.predicates)
        return self.validate(data, targets), contexts

    def validate(self, data: NodeStatements, targets: dict[URIRef, set[str]]) -> list[ShapeResult]:
        """Each shape on its targets, in `data` (the targets' statements, read with `statements`)."""
        results: list[ShapeResult] = []
        for shape, focus in targets.items():
            checks = self.checks.get(shape)
            if checks is not None:
                for node in sorted(focus):
                    results += [ShapeResult(node, found.message, found.path, found.value)
                                for found in check_node(checks, data.values(node))]  # fmt: skip
                continue
            # In chunks: pySHACL compares each focus node with the list it was given (1,800 nodes at once took
            # 6.4 s, in chunks of 200 a hundredth of that).
            for chunk in _chunks(sorted(focus), FOCUS_PER_RUN):
                results += self._validate(data.graph, shape, chunk)
        return results

    def _validate(self, data: Graph, shape: URIRef, focus: list[str]) -> list[ShapeResult]:
        # pySHACL parses through rdflib, whose parser is not safe across threads (services/sparql/parser.py).
        with exclusive():
            _, report, _ = pyshacl.validate(
                data,
                shacl_graph=self.graph,
                advanced=True,
                inplace=True,  # the graph is this check's own copy: no second copy for pySHACL
                allow_warnings=True,
                allow_infos=True,
                focus_nodes=[URIRef(node[1:-1]) for node in focus],
                use_shapes=[shape],
            )
        return list(_results(report))


def statements(
    store: Store, nodes: list[str], predicates: frozenset[str] | None, delta: Delta | None = None
) -> tuple[NodeStatements, dict[str, Context]]:
    """The nodes' statements with these predicates (None: all), and each node's context. Those of the fresh
    nodes of `delta` are its own triples about them (the store holds no other), the others' are asked."""
    data = NodeStatements()
    contexts: dict[str, dict[str, object]] = {}
    wanted = None if predicates is None else sorted({*predicates, *TIMES, *ACTORS, str(RDF.type)})
    if delta is not None and delta.fresh:
        told = [node for node in nodes if node in delta.fresh]
        for predicate in delta.predicates() if wanted is None else set(wanted) & delta.predicates():
            for node in told:
                # Once each, as the store holds a triple (a batch may carry one twice: a count must not see two).
                for fact in {fact.object_text: fact for fact in delta.about(predicate, node)}.values():
                    data.add(node, predicate, fact.object)
                    _note_context(contexts.setdefault(node, {}), predicate, fact.object)
        nodes = [node for node in nodes if node not in delta.fresh]
    for chunk in _chunks(nodes):
        text = "SELECT ?s ?p ?o WHERE { ?s ?p ?o }"
        if wanted is not None:
            # A FILTER, not a second VALUES: the embedded store joins two VALUES blocks six times slower.
            listed = ", ".join(f"<{predicate}>" for predicate in wanted)
            text = f"SELECT ?s ?p ?o WHERE {{ ?s ?p ?o FILTER (?p IN ({listed})) }}"
        bound = bind_rows(text, ["s"], [[NamedNode(node[1:-1])] for node in chunk], wrap=store.wraps_values)
        for row in select(store, bound).rows:
            subject, predicate, value = term_text(row["s"]), row["p"].value, row["o"]
            data.add(subject, predicate, value)
            _note_context(contexts.setdefault(subject, {}), predicate, value)
    return data, {node: Context.of(found) for node, found in contexts.items()}


def generated_by_newly_performed(store: Store, delta: Delta) -> set[str]:
    """What the activities the batch names a performer of generated, when the store held them before (a late
    link): their findings' robot becomes that performer, so they are checked again. What a fresh activity
    generated is among the batch's own triples, so named by it already."""
    activities = sorted({fact.subject_text for fact in delta.with_predicate(PERFORMED_BY)} - delta.fresh)
    generated: set[str] = set()
    for chunk in _chunks(activities):
        text = f"SELECT ?s WHERE {{ ?s <{GENERATED_BY}> ?o }}"
        bound = bind_rows(text, ["o"], [[NamedNode(node[1:-1])] for node in chunk], wrap=store.wraps_values)
        generated.update(term_text(row["s"]) for row in select(store, bound).rows)
    return generated


def robots_of_generating(store: Store, activities: set[str], delta: Delta | None = None) -> dict[str, object]:
    """The robot that performed each of these activities (N-Triples texts): from the batch's own triples for
    those it introduced, else asked of the store."""
    found: dict[str, object] = {}
    asked = sorted(activities)
    if delta is not None and delta.fresh:
        for activity in [activity for activity in asked if activity in delta.fresh]:
            performed = delta.about(PERFORMED_BY, activity)
            if performed:
                found[activity] = performed[0].object
        asked = [activity for activity in asked if activity not in delta.fresh]
    for chunk in _chunks(asked):
        text = f"SELECT ?s ?o WHERE {{ ?s <{PERFORMED_BY}> ?o }}"
        bound = bind_rows(text, ["s"], [[NamedNode(node[1:-1])] for node in chunk], wrap=store.wraps_values)
        for row in select(store, bound).rows:
            found.setdefault(term_text(row["s"]), row["o"])
    return found


def read_predicates(rules: list[ShapeRule]) -> frozenset[str] | None:
    """What checking these rules together reads of a node: every predicate one of them reads (None: all)."""
    found: set[str] = set()
    for rule in rules:
        if rule.predicates is None:
            return None
        found |= rule.predicates
    return frozenset(found)


def _note_context(context: dict[str, object], predicate: str, value: object) -> None:
    """The start time, else the end, else the generation time (xsd:dateTime only), and the performing robot."""
    if predicate in TIMES and getattr(getattr(value, "datatype", None), "value", None) == XSD_DATETIME:
        rank = TIMES.index(predicate)
        if rank < int(context.get("rank", len(TIMES))):  # type: ignore[call-overload]
            context["time"], context["rank"] = value, rank
    elif predicate == PERFORMED_BY:
        context.setdefault("performer", value)
    elif predicate == ATTRIBUTED_TO:
        context.setdefault("attributed", value)
    elif predicate == GENERATED_BY:
        context.setdefault("generated_by", value)
    elif predicate == SENDER or (predicate == RDF_TYPE and getattr(value, "value", None) == MESSAGE):
        context["said"] = True


def _results(report: Graph) -> Iterator[ShapeResult]:
    for result in report.subjects(RDF.type, SH.ValidationResult):
        focus = report.value(result, SH.focusNode)
        if not isinstance(focus, URIRef):
            continue
        message = report.value(result, SH.resultMessage)
        path = report.value(result, SH.resultPath)
        value = report.value(result, SH.value)
        yield ShapeResult(
            focus=f"<{focus}>",
            message=str(message) if message is not None else "Does not meet the rule's shape",
            path=str(path) if isinstance(path, URIRef) else None,
            value=_shown(value),
        )


def _shown(value: Node | None) -> str | None:
    if value is None or isinstance(value, BNode):
        return None
    return str(value) if isinstance(value, URIRef | RdfLiteral) else None


# --- the shapes graph --------------------------------------------------------------------------------


def _target_queries(graph: Graph, shape: Node) -> list[str]:
    """SELECT queries of ?this, one per target declaration of the shape (candidates are bound into their WHERE:
    a SPARQL-based target's own select too, so it reads only what the candidates say)."""
    nodes, classes, predicates, asked = _own_targets(graph, shape)
    told = [
        f"SELECT DISTINCT ?this WHERE {{ VALUES ?this {{ {node} }} ?this ?anyPredicate ?anyObject }}" for node in nodes
    ]
    told += [f"SELECT DISTINCT ?this WHERE {{ ?this a <{cls}> }}" for cls in classes]
    told += [f"SELECT DISTINCT ?this WHERE {{ ?this <{predicate}> ?anyObject }}" for predicate in predicates]
    return told + [target.query for target in asked]


@dataclass(frozen=True)
class Asked:
    """A target the store is asked for: the objects of a predicate (`predicate`), or a SPARQL-based target."""

    query: str
    predicate: str | None = None


def _own_targets(graph: Graph, shape: Node) -> tuple[set[str], list[URIRef], list[URIRef], list[Asked]]:
    """A shape's targets a node's own statements tell — its IRI (`sh:targetNode`), a type (`sh:targetClass`), a
    predicate it is the subject of (`sh:targetSubjectsOf`) — and the queries of the others (the objects of a
    predicate, a SPARQL-based target)."""
    nodes = {f"<{node}>" for node in graph.objects(shape, SH.targetNode) if isinstance(node, URIRef)}
    classes = [cls for cls in graph.objects(shape, SH.targetClass) if isinstance(cls, URIRef)]
    predicates = [p for p in graph.objects(shape, SH.targetSubjectsOf) if isinstance(p, URIRef)]
    asked = [Asked(f"SELECT DISTINCT ?this WHERE {{ ?anySubject <{p}> ?this }}", str(p))
             for p in graph.objects(shape, SH.targetObjectsOf) if isinstance(p, URIRef)]  # fmt: skip
    asked += [
        Asked(str(text)) for target in graph.objects(shape, SH.target) if (text := graph.value(target, SH.select))
    ]
    return nodes, classes, predicates, asked


def _ask_targets(store: Store, query: str, chunk: list[str] | None) -> set[str]:
    if chunk is not None:
        # Virtuoso 7 skips some FILTERs of a group that opens with VALUES (`_with_values`): it is asked the join.
        asked = query if store.wraps_values else _membership(query)
        query = bind_rows(asked, ["this"], [[NamedNode(node[1:-1])] for node in chunk], wrap=store.wraps_values)
    return {term_text(row["this"]) for row in select(store, query).rows if isinstance(row.get("this"), NamedNode)}


def _membership(query: str) -> str:
    """A target query asked of given nodes: whether each one is a target, asked with EXISTS, which stops at the
    first match. Joined instead, a node would come back once per statement that makes it a target (a SPARQL
    target `?this ?p ?o`: every statement of the node), and a hub (a model every activity used, for
    `sh:targetObjectsOf`) with every subject the store holds for it, a number that grows with the log."""
    opening, end = top_level_where(query), top_level_where_end(query)
    if opening is None or end is None:
        return query
    prologue = query[: max(0, query.upper().find("SELECT"))]  # its PREFIXes, if any
    return f"{prologue}SELECT ?this WHERE {{ FILTER EXISTS {{ {query[opening:end]} }} }}"


def _read_predicates(graph: Graph) -> frozenset[str] | None:
    """The predicates the shapes' paths read from a focus node, or None when a shape reads further (a path that
    is not one IRI, a SPARQL constraint, a nested shape): then every statement of the node is read."""
    if any(True for _ in graph.subjects(SH.sparql, None)) or any(True for _ in graph.subjects(SH.node, None)):
        return None
    predicates = set()
    for path in graph.objects(None, SH.path):
        if not isinstance(path, URIRef):
            return None
        predicates.add(str(path))
    return frozenset(predicates)


def _chunks(items: list[str], size: int = NODES_PER_QUERY) -> Iterator[list[str]]:
    for start in range(0, len(items), size):
        yield items[start : start + size]
