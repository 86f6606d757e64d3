"""The compiled SHACL check (rules/shape_check.py) finds what pySHACL finds: the same results (focus, message,
path, value) for every shipped shape and for shapes using each constraint it compiles, on nodes whose values
are of every kind a robot may send (ill-typed literals, times with and without a zone, strings against number
bounds, IRIs and blank nodes where literals are expected). One difference is by design: a finding shows a value
as the robot wrote it ("NaN", "…Z"), where pySHACL shows rdflib's canonical form of it ("nan", "…+00:00"); the
test matches both to the statement they name."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

import pytest
from pyoxigraph import BlankNode, Literal, NamedNode, Quad

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.rules.catalog import Rule, RuleCatalog
from segb_server.backend.services.rules.shape_check import as_rdflib
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.services.views.shape_checks import check_rules
from segb_server.backend.store.base import select
from segb_server.backend.store.oxigraph import OxigraphStore

XSD = "http://www.w3.org/2001/XMLSchema#"
RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
EX = "http://example.org/"
PREDICATES = [
    "http://www.w3.org/ns/prov#startedAtTime",
    "http://www.w3.org/ns/prov#endedAtTime",
    "http://www.w3.org/ns/prov#generatedAtTime",
    "http://www.w3.org/ns/sosa/resultTime",
    "http://www.gsi.upm.es/ontologies/onyx/ns#hasEmotionIntensity",
    "http://www.gsi.upm.es/ontologies/onyx/ns#algorithmConfidence",
    "http://schema.org/text",
    "http://schema.org/version",
    EX + "count",
]
TYPES = [
    "http://www.gsi.upm.es/ontologies/segb/ns#LoggedActivity",
    "http://schema.org/Message",
    EX + "Thing",
]
VALUES: list[object] = [
    Literal("2026-01-05T08:00:00Z", datatype=NamedNode(XSD + "dateTime")),
    Literal("2026-01-05T08:00:00", datatype=NamedNode(XSD + "dateTime")),  # no zone
    Literal("yesterday", datatype=NamedNode(XSD + "dateTime")),  # ill-typed
    Literal("2026-01-05", datatype=NamedNode(XSD + "date")),
    Literal("2026-01-05T08:00:00Z"),  # a plain string
    Literal("0.5", datatype=NamedNode(XSD + "decimal")),
    Literal("1", datatype=NamedNode(XSD + "integer")),
    Literal("-0.0", datatype=NamedNode(XSD + "double")),
    Literal("1.0000001", datatype=NamedNode(XSD + "double")),
    Literal("NaN", datatype=NamedNode(XSD + "double")),
    Literal("INF", datatype=NamedNode(XSD + "float")),
    Literal("high", datatype=NamedNode(XSD + "decimal")),  # ill-typed
    Literal("2", datatype=NamedNode(XSD + "int")),
    Literal("true", datatype=NamedNode(XSD + "boolean")),
    Literal("0.7"),  # a number written as a string
    Literal("hola", language="es"),
    Literal("", datatype=NamedNode(XSD + "string")),
    Literal("b", datatype=NamedNode(EX + "custom")),
    NamedNode(EX + "value"),
    BlankNode("value"),
]
# Shapes using every constraint the check compiles, with bounds of each kind.
CONSTRAINTS = """
@prefix sh: <http://www.w3.org/ns/shacl#> .
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
@prefix rdf: <http://www.w3.org/1999/02/22-rdf-syntax-ns#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
@prefix ex: <http://example.org/> .

ex:counted a sh:NodeShape ; sh:targetClass ex:Thing ;
    sh:property [ sh:path ex:count ; sh:minCount 2 ; sh:maxCount 3 ; sh:message "two or three counts" ] ;
    sh:property [ sh:path <http://schema.org/text> ; sh:maxCount 1 ; sh:message "one text at most" ] .
ex:typed a sh:NodeShape ; sh:targetClass ex:Thing ; sh:targetSubjectsOf ex:count ;
    sh:property [ sh:path ex:count ; sh:datatype xsd:integer ; sh:message "an integer" ] ;
    sh:property [ sh:path <http://schema.org/text> ; sh:datatype rdf:langString ;
                  sh:message "a text with a language" ] ;
    sh:property [ sh:path <http://schema.org/version> ; sh:datatype xsd:string ; sh:message "a string" ] ;
    sh:property [ sh:path <http://www.w3.org/ns/prov#endedAtTime> ; sh:datatype rdfs:Literal ;
                  sh:message "a literal" ] ;
    sh:property [ sh:path <http://www.w3.org/ns/prov#generatedAtTime> ; sh:datatype xsd:date ; sh:message "a date" ] ;
    sh:property [ sh:path <http://www.w3.org/ns/sosa/resultTime> ; sh:datatype ex:custom ; sh:message "custom" ] .
ex:ranged a sh:NodeShape ; sh:targetClass ex:Thing ;
    sh:property [ sh:path ex:count ; sh:minExclusive 0.5e0 ; sh:maxExclusive 2 ; sh:message "in (0.5, 2)" ] ;
    sh:property [ sh:path <http://www.w3.org/ns/prov#startedAtTime> ;
                  sh:minInclusive "2026-01-01T00:00:00Z"^^xsd:dateTime ; sh:message "this year" ] ;
    sh:property [ sh:path <http://schema.org/version> ; sh:maxInclusive "m" ; sh:message "up to m" ] ;
    sh:property [ sh:path <http://www.w3.org/ns/prov#generatedAtTime> ;
                  sh:maxExclusive "2026-02-01"^^xsd:date ; sh:message "before February" ] .
"""
# Shapes the check does not compile: pySHACL checks them.
NOT_COMPILED = """
@prefix sh: <http://www.w3.org/ns/shacl#> .
@prefix ex: <http://example.org/> .
ex:classed a sh:NodeShape ; sh:targetClass ex:Thing ;
    sh:property [ sh:path ex:count ; sh:class ex:Thing ; sh:message "a thing" ] .
ex:sequence a sh:NodeShape ; sh:targetClass ex:Thing ;
    sh:property [ sh:path ( ex:count ex:count ) ; sh:minCount 1 ; sh:message "a count of a count" ] .
ex:unsaid a sh:NodeShape ; sh:targetClass ex:Thing ;
    sh:property [ sh:path ex:count ; sh:minCount 1 ] .
"""


def _rule(rule_id: str, shapes: str) -> Rule:
    return Rule(rule_id, rule_id, "warning", "", Path(f"{rule_id}.ttl"), shapes=shapes)


def _store() -> OxigraphStore:
    """Nodes of every type, each with one value of every kind for one predicate, and some with none or two."""
    store = OxigraphStore("urn:test")
    quads: list[Quad] = []
    number = 0
    for kind in TYPES:
        for predicate in PREDICATES:
            for value in VALUES:
                node = NamedNode(f"{EX}node{number}")
                number += 1
                quads.append(Quad(node, NamedNode(RDF + "type"), NamedNode(kind)))
                quads.append(Quad(node, NamedNode(predicate), value))  # type: ignore[arg-type]
        pair = NamedNode(f"{EX}pair{number}")
        number += 1
        quads += [Quad(pair, NamedNode(RDF + "type"), NamedNode(kind)),
                  Quad(pair, NamedNode(EX + "count"), Literal("1", datatype=NamedNode(XSD + "integer"))),
                  Quad(pair, NamedNode(EX + "count"), Literal("3", datatype=NamedNode(XSD + "integer"))),
                  Quad(pair, NamedNode("http://schema.org/text"), Literal("a")),
                  Quad(pair, NamedNode("http://schema.org/text"), Literal("b", language="en"))]  # fmt: skip
        quads.append(Quad(NamedNode(f"{EX}bare{number}"), NamedNode(RDF + "type"), NamedNode(kind)))
        number += 1
    quads.append(Quad(NamedNode(EX + "untyped"), NamedNode(EX + "count"), NamedNode(EX + "node0")))
    # Models an activity used: some with a version (of every kind), some with none.
    used = NamedNode("http://www.gsi.upm.es/ontologies/segb/ns#usedMLModel")
    versions = PREDICATES.index("http://schema.org/version") * len(VALUES)
    for model in [*range(versions, versions + len(VALUES)), 0, 1]:
        quads.append(Quad(NamedNode(EX + "act"), used, NamedNode(f"{EX}node{model}")))
    quads.append(Quad(NamedNode(EX + "act"), NamedNode(PREDICATES[0]), BlankNode("b")))
    store.apply(quads, 1)
    return store


def _results(rule: Rule, compiled: bool, store: OxigraphStore, named: set[str] | None) -> Counter[tuple[object, ...]]:
    """Each result as (focus, message, path, the statement its value is the object of)."""
    _, found = check_rules([ShapeRule(rule, compiled=compiled)], store, named)[rule.id]
    return Counter((unit, row["message"], row["path"], _statement(store, unit, row["path"], row["value"]))
                   for unit, rows in found.items() for _, _, _, row in rows)  # fmt: skip


def _statement(store: OxigraphStore, focus: str, path: object, shown: object) -> str | None:
    """The object (N-Triples) of the focus node's statement whose value a result shows, as written or as rdflib's
    canonical form of it."""
    if shown is None:
        return None
    values = [row["o"] for row in select(store, f"SELECT ?o WHERE {{ {focus} <{path}> ?o }}").rows]
    matching = [str(value) for value in values if shown in (value.value, str(as_rdflib(value)))]
    assert len(matching) == 1, (focus, path, shown, matching)
    return matching[0]


SHIPPED = [rule for rule in RuleCatalog(PACKAGE_ROOT / "rules").shapes()]


@pytest.mark.parametrize("rule", [*SHIPPED, _rule("constraints", CONSTRAINTS)], ids=lambda rule: rule.id)
def test_a_compiled_shape_finds_what_pyshacl_finds(rule: Rule) -> None:
    assert all(checks is not None for checks in ShapeRule(rule).checks.values()), "every shape here compiles"
    store = _store()
    try:
        compiled = _results(rule, True, store, None)
        assert compiled == _results(rule, False, store, None)
        # Every property shape finds something: an empty answer would prove nothing.
        assert {message for _, message, _, _ in compiled} == set(re.findall(r'sh:message "([^"]+)"', rule.shapes or ""))
        # Checking named nodes (a batch's) finds the same as checking every target.
        named = {f"<{EX}node{number}>" for number in range(0, 600, 7)} | {f"<{EX}untyped>", f"<{EX}act>"}
        assert _results(rule, True, store, named) == _results(rule, False, store, named)
    finally:
        store.close()


def test_a_shape_the_check_does_not_compile_is_checked_by_pyshacl() -> None:
    rule = _rule("not-compiled", NOT_COMPILED)
    assert set(ShapeRule(rule).checks.values()) == {None}
    store = _store()
    try:
        found = _results(rule, True, store, None)
    finally:
        store.close()
    messages = {message for _, message, _, _ in found}
    assert {"a thing", "a count of a count"} <= messages  # pySHACL's own results, its generated message too
    assert any(message.startswith("Less than 1 values on <") for message in messages)


def test_a_value_that_cannot_be_compared_with_a_decimal_bound_is_a_finding() -> None:
    """NaN against a decimal bound: Python's decimals raise where SPARQL's comparison is false (pySHACL stops on
    it); the compiled check reports the value, as SHACL says of a comparison that is not true."""
    rule = _rule("decimal", CONSTRAINTS.replace("0.5e0", "0.5"))
    store = _store()
    try:
        found = _results(rule, True, store, None)
    finally:
        store.close()
    nan = str(Literal("NaN", datatype=NamedNode(XSD + "double")))
    assert any(message == "in (0.5, 2)" and value == nan for _, message, _, value in found)
