"""SHACL Core shapes checked in plain Python, for the shapes simple enough to compile: pySHACL's answer without
pySHACL's cost.

Most audit shapes are node shapes whose property shapes each read one predicate of the focus node and bound it
by count, datatype or value range (`sh:minCount`, `sh:maxCount`, `sh:datatype`, `sh:minInclusive`,
`sh:maxInclusive`, `sh:minExclusive`, `sh:maxExclusive`), each with one `sh:message`. Checking such a shape needs
only the focus node's values for that predicate. pySHACL builds a shapes graph, a data graph and a report graph
for it, under the lock rdflib's parser needs: in the views' upkeep it was a third of the work of a post. Here a
shape is compiled once into `PropertyCheck`s, and a node is checked against its values directly.

A shape using anything else (a path of several steps, `sh:node`, `sh:class`, SPARQL constraints, a
deactivated shape, two messages) does not compile: `compile_shape` answers None and the rule is checked with
pySHACL as before. What each constraint means follows the SHACL specification (§4) as pySHACL 0.40 implements it,
down to its edge cases (ill-typed literals, comparisons of values of different kinds); the differential test
(`tests/services/test_shape_check.py`) checks both on the same nodes.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import date, datetime, time
from decimal import Decimal

from pyoxigraph import BlankNode, Literal, NamedNode
from rdflib import RDF, RDFS, SH, XSD, BNode, Graph, URIRef
from rdflib.term import Literal as RdfLiteral
from rdflib.term import Node

# What a node shape may say besides its targets and property shapes for it to compile: nothing that changes
# which results there are or what they say (a name, a comment, a severity: the rule's header sets severity).
_NODE_SHAPE_AS_IS = {RDF.type, SH.property, SH.targetClass, SH.targetNode, SH.targetSubjectsOf, SH.targetObjectsOf,
                     SH.target, SH.severity, RDFS.label, RDFS.comment, SH.name, SH.description}  # fmt: skip
_PROPERTY_AS_IS = {RDF.type, SH.path, SH.message, SH.severity, SH.name, SH.description, SH.order, SH.group,
                   RDFS.label, RDFS.comment}  # fmt: skip
_BOUNDS = {SH.minInclusive: "minInclusive", SH.maxInclusive: "maxInclusive", SH.minExclusive: "minExclusive",
           SH.maxExclusive: "maxExclusive"}  # fmt: skip
_COMPILED = {SH.minCount, SH.maxCount, SH.datatype, *_BOUNDS}
# The Python type of a well-formed literal of each datatype (as rdflib reads its lexical form): a literal of one
# of these datatypes whose value is not of that type is ill-typed, and does not match `sh:datatype`.
_VALUE_TYPES: dict[URIRef, type | tuple[type, ...]] = {
    XSD.string: (str, bytes), RDF.langString: (str, bytes), XSD.integer: int, XSD.float: float,
    XSD.decimal: Decimal, XSD.boolean: bool, XSD.date: date, XSD.time: time, XSD.dateTime: datetime,
}  # fmt: skip


@dataclass(frozen=True)
class Violation:
    """One validation result of a focus node: its message, the path it concerns, and the value it names."""

    message: str
    path: str
    value: str | None


@dataclass(frozen=True)
class PropertyCheck:
    """A property shape of one predicate: its constraints, and the message its results carry."""

    path: str
    message: str
    min_count: int | None = None
    max_count: int | None = None
    datatype: URIRef | None = None
    bounds: tuple[tuple[str, RdfLiteral], ...] = field(default=())  # (constraint, its bound) in SHACL's order

    def violations(self, values: Sequence[object]) -> list[Violation]:
        """The results for a focus node whose values (pyoxigraph terms) for `path` are `values`."""
        found: list[Violation] = []
        if self.min_count is not None and len(values) < self.min_count:
            found.append(Violation(self.message, self.path, None))
        if self.max_count is not None and len(values) > self.max_count:
            found.append(Violation(self.message, self.path, None))
        if self.datatype is None and not self.bounds:
            return found
        for value in values:
            node = as_rdflib(value)
            if self.datatype is not None and not matches_datatype(node, self.datatype):
                found.append(Violation(self.message, self.path, _shown(value)))
            for constraint, bound in self.bounds:
                if not within(node, constraint, bound):
                    found.append(Violation(self.message, self.path, _shown(value)))
        return found


def compile_shape(graph: Graph, shape: Node) -> list[PropertyCheck] | None:
    """A node shape as the checks of its property shapes, or None when it says more than those can check."""
    if any(predicate not in _NODE_SHAPE_AS_IS for predicate in graph.predicates(shape, None)):
        return None
    checks = []
    for prop in graph.objects(shape, SH.property):
        check = _compile_property(graph, prop)
        if check is None:
            return None
        checks.append(check)
    return checks


def _compile_property(graph: Graph, prop: Node) -> PropertyCheck | None:
    said: dict[Node, list[Node]] = {}
    for predicate, value in graph.predicate_objects(prop):
        said.setdefault(predicate, []).append(value)
    if any(p not in _PROPERTY_AS_IS and p not in _COMPILED for p in said) or any(len(v) > 1 for v in said.values()):
        return None  # another constraint, or a parameter given twice (pySHACL's own checks then apply)
    path, message = said.get(SH.path, [None])[0], said.get(SH.message, [None])[0]
    if not isinstance(path, URIRef) or not isinstance(message, RdfLiteral):
        return None  # a path of several steps, or pySHACL's generated message
    counts = {name: said.get(name, [None])[0] for name in (SH.minCount, SH.maxCount)}
    if any(count is not None and not _is_count(count) for count in counts.values()):
        return None
    datatype = said.get(SH.datatype, [None])[0]
    if datatype is not None and not isinstance(datatype, URIRef):
        return None
    bounds = [(name, said[term][0]) for term, name in _BOUNDS.items() if term in said]
    if any(not isinstance(bound, RdfLiteral) for _, bound in bounds):
        return None
    return PropertyCheck(
        path=str(path),
        message=str(message),
        min_count=_count(counts[SH.minCount]),
        max_count=_count(counts[SH.maxCount]),
        datatype=datatype,
        bounds=tuple((name, bound) for name, bound in bounds if isinstance(bound, RdfLiteral)),
    )


def _is_count(value: Node) -> bool:
    return isinstance(value, RdfLiteral) and isinstance(value.value, int) and not isinstance(value.value, bool)


def _count(value: Node | None) -> int | None:
    return int(value.value) if isinstance(value, RdfLiteral) else None


def check_node(checks: Iterable[PropertyCheck], values: Mapping[str, Sequence[object]]) -> list[Violation]:
    """Every result of a compiled shape for one focus node, given its values by predicate."""
    return [violation for check in checks for violation in check.violations(values.get(check.path, ()))]


# --- what each constraint means -------------------------------------------------------------------------


def matches_datatype(node: Node, datatype: URIRef) -> bool:
    """`sh:datatype`: a literal of that datatype that is well formed (SPARQL's datatype function; a plain
    literal is an xsd:string, a literal with a language an rdf:langString)."""
    if not isinstance(node, RdfLiteral):
        return False
    if node.datatype == datatype:
        return not node.ill_typed and _well_typed(node, datatype)
    if datatype == RDFS.Literal:
        return True  # every literal is one
    if datatype == RDFS.Datatype:
        return node.datatype is not None
    if node.datatype is None and node.language is None and datatype == XSD.string:
        return _well_typed(node, datatype)
    if node.language and datatype == RDF.langString:
        return _well_typed(node, datatype)
    return False


def _well_typed(node: RdfLiteral, datatype: URIRef) -> bool:
    expected = _VALUE_TYPES.get(datatype)
    return expected is None or isinstance(node.value, expected)  # a datatype rdflib does not read: as is


def within(node: Node, constraint: str, bound: RdfLiteral) -> bool:
    """A value range constraint: true when the SPARQL comparison of the value with the bound holds; a value
    that cannot be compared with it (an IRI, a blank node, a string against a number) does not conform."""
    if not isinstance(node, RdfLiteral):
        return False
    if isinstance(node.value, str) != isinstance(bound.value, str):
        return False
    try:
        order = _compare(node, bound)
    except (TypeError, NotImplementedError, ArithmeticError):  # ArithmeticError: a decimal against NaN
        return False
    if constraint == "minInclusive":
        return order >= 0
    if constraint == "maxInclusive":
        return order <= 0
    if constraint == "minExclusive":
        return order > 0
    return order < 0  # maxExclusive


def _compare(value: RdfLiteral, bound: RdfLiteral) -> int:
    """1 when the value is above the bound, 0 when equal, else -1 (TypeError when they cannot be compared). Dates
    and times by their values, so that one with a zone and one without cannot be compared (rdflib would order
    them anyway); everything else by rdflib's literal order, which compares numbers by value."""
    if value.eq(bound):
        return 0
    if type(value.value) in (datetime, time):
        if value.value == bound.value:
            return 0
        return 1 if value.value > bound.value else -1
    return 1 if value > bound else -1


# --- terms ---------------------------------------------------------------------------------------------


def as_rdflib(term: object) -> Node:
    """A store's term as rdflib's, whose literals carry their value and whether their lexical form is ill-typed."""
    if isinstance(term, NamedNode):
        return URIRef(term.value)
    if isinstance(term, Literal):
        if term.language:
            return RdfLiteral(term.value, lang=term.language)
        return RdfLiteral(term.value, datatype=URIRef(term.datatype.value))
    return BNode(getattr(term, "value", str(term)))


def _shown(term: object) -> str | None:
    """What a finding shows of a value: an IRI or a literal's lexical form; nothing of a blank node."""
    if isinstance(term, BlankNode):
        return None
    return getattr(term, "value", None)
