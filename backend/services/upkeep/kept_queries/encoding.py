"""RDF terms written so that SQLite can sort and compare them as SPARQL would for the reports: a sort key whose
byte order is ORDER BY's order, and typed filter values."""

from __future__ import annotations

import struct
from datetime import UTC, datetime
from decimal import Decimal, InvalidOperation

from pyoxigraph import BlankNode, Literal, NamedNode

from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text

XSD = "http://www.w3.org/2001/XMLSchema#"
NUMERIC = {XSD + name for name in ("integer", "decimal", "float", "double", "long", "int", "short", "byte")}
DATE_TIME = XSD + "dateTime"
SEPARATOR = "\x00"  # below every character a value holds, so a shorter tuple sorts first


def sort_key(terms: list[Term | None]) -> str:
    """ORDER BY's order as byte order: unbound, then blank nodes, IRIs, numbers (by value), date-times (by
    instant), other literals (by text) — the order the stores use for the values reports sort by."""
    return SEPARATOR.join(_sort_part(term) for term in terms)


def _sort_part(term: Term | None) -> str:
    if term is None:
        return "0"
    if isinstance(term, BlankNode):
        return "1" + term.value
    if isinstance(term, NamedNode):
        return "2" + term.value
    number = numeric_value(term)
    if number is not None:
        return "3" + _sortable_float(number)
    moment = instant(term)
    if moment is not None:
        return "4" + moment
    return "5" + term.value


def numeric_value(term: Term | None) -> float | None:
    if not isinstance(term, Literal) or term.datatype.value not in NUMERIC:
        return None
    try:
        return float(Decimal(term.value))
    except (InvalidOperation, ValueError):
        return None


def instant(term: Term | None) -> str | None:
    """A date-time with a zone, as a fixed-width UTC text that sorts by instant; None for anything else."""
    if not isinstance(term, Literal) or term.datatype.value != DATE_TIME:
        return None
    try:
        moment = datetime.fromisoformat(term.value.replace("Z", "+00:00"))
    except ValueError:
        return None
    if moment.tzinfo is None:
        return None
    return moment.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%f")


def filter_value(term: Term | None, kind: str) -> str | float | None:
    """What a filter of parameter type `kind` compares: the N-Triples text of an IRI, a date-time's instant, a
    number's value, a string's text; None when the column is unbound or of another type."""
    if term is None:
        return None
    if kind == "iri":
        return term_text(term) if isinstance(term, NamedNode) else None
    if kind == "dateTime":
        return instant(term)
    if kind in ("decimal", "integer"):
        return numeric_value(term)
    return term.value if isinstance(term, Literal) else None


def _sortable_float(number: float) -> str:
    """A float as 16 hex digits whose text order is the numbers' order (IEEE 754 bits, sign-adjusted)."""
    bits = struct.unpack(">Q", struct.pack(">d", number))[0]
    bits = bits ^ 0xFFFFFFFFFFFFFFFF if bits >> 63 else bits | 1 << 63
    return f"{bits:016x}"
