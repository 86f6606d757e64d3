"""Comparing RDF graphs triple for triple."""

from __future__ import annotations

from datetime import datetime
from decimal import Decimal

from pyoxigraph import Literal, RdfFormat, parse

XSD = "http://www.w3.org/2001/XMLSchema#"
NUMERIC = {XSD + name for name in ("double", "float", "decimal", "integer")}
# Stores encode every integer type as xsd:integer (the embedded store gives "6"^^xsd:long back as 6).
INTEGER_TYPES = {XSD + name for name in ("long", "int", "short", "byte", "nonNegativeInteger", "unsignedLong")}


def triples(data: bytes | str, rdf_format: RdfFormat = RdfFormat.N_TRIPLES) -> set[tuple[str, str, str]]:
    """The set of triples, each as its N-Triples terms (exact lexical forms)."""
    raw = data.encode() if isinstance(data, str) else data
    return {(str(q.subject), str(q.predicate), str(q.object)) for q in parse(raw, rdf_format)}


def value_triples(data: bytes | str, rdf_format: RdfFormat = RdfFormat.N_TRIPLES) -> set[tuple[str, str, object]]:
    """Triples with numeric and date-time literals compared by value.

    Both stores keep typed literals as values and give back their canonical spelling: the client's
    `"8.7e-01"^^xsd:double` comes back as `"0.87"`, `...09:00:07+00:00` as `...09:00:07Z`. Same value, other
    spelling; everything else is compared exactly.
    """
    raw = data.encode() if isinstance(data, str) else data
    return {(str(q.subject), str(q.predicate), _value(q.object)) for q in parse(raw, rdf_format)}


def _value(term: object) -> object:
    if not isinstance(term, Literal):
        return str(term)
    datatype = term.datatype.value
    if datatype in INTEGER_TYPES:
        datatype = XSD + "integer"
    if datatype in NUMERIC:
        return (datatype, round(float(Decimal(term.value)), 6))
    if datatype == XSD + "dateTime":
        return (datatype, datetime.fromisoformat(term.value.replace("Z", "+00:00")))
    return str(term)
