"""RDF terms written so that SQLite can sort and compare them as SPARQL would for the reports: a sort key whose
byte order is ORDER BY's order, and typed filter values."""

from __future__ import annotations

import struct
from datetime import UTC, datetime, timedelta
from decimal import Decimal, InvalidOperation

from pyoxigraph import BlankNode, Literal, NamedNode

from segb_server.backend.services.views.kept_queries.key_namespaces import Namespaces, number_of, order_digits
from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text

XSD = "http://www.w3.org/2001/XMLSchema#"
NUMERIC = {XSD + name for name in ("integer", "decimal", "float", "double", "long", "int", "short", "byte")}
DATE_TIME = XSD + "dateTime"
SEPARATOR = "\x00"  # below every character a value holds, so a shorter tuple sorts first
FIRST_DAY = datetime(1, 1, 1, tzinfo=UTC)
INSTANT_DIGITS = 10  # microseconds since year 1 in ORDER_DIGITS: 60 bits, past year 9999
NO_NAMESPACES = Namespaces()


def sort_key(terms: list[Term | None], namespaces: Namespaces = NO_NAMESPACES) -> str:
    """ORDER BY's order as byte order: unbound, then blank nodes, IRIs, numbers (by value), date-times (by
    instant), other literals (by text) — the order the stores use for the values reports sort by. IRIs are
    written with their table's `namespaces` (`key_namespaces.py`): keys of one table compare with each other."""
    return SEPARATOR.join(_sort_part(term, namespaces) for term in terms)


def _sort_part(term: Term | None, namespaces: Namespaces) -> str:
    if term is None:
        return "0"
    if isinstance(term, BlankNode):
        return "1" + term.value
    if isinstance(term, NamedNode):
        return "2" + namespaces.iri_part(term.value)
    number = numeric_value(term)
    if number is not None:
        return "3" + _sortable_float(number)
    micros = instant_micros(term)
    if micros is not None:  # 10 characters where the instant's text took 26, in every key and index
        return "4" + order_digits(micros, INSTANT_DIGITS)
    return "5" + term.value


def instant_of_part(digits: str) -> str:
    """The instant a key's date-time part (after its kind) stands for, as `iso_time` reads it."""
    return (FIRST_DAY + timedelta(microseconds=number_of(digits))).isoformat(timespec="microseconds")


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


def instant_micros(term: Term | None) -> int | None:
    """A date-time with a zone as microseconds since the first day of year 1 (UTC); None for anything else."""
    if not isinstance(term, Literal) or term.datatype.value != DATE_TIME:
        return None
    try:
        moment = datetime.fromisoformat(term.value.replace("Z", "+00:00"))
        if moment.tzinfo is None:
            return None
        micros = (moment - FIRST_DAY) // timedelta(microseconds=1)
    except (ValueError, OverflowError):
        return None
    return micros if micros >= 0 else None  # before year 1 in UTC: not an instant the keys can hold


def filter_value(term: Term | None, kind: str) -> str | float | int | None:
    """What a filter of parameter type `kind` compares: the N-Triples text of an IRI, a date-time's instant (in
    microseconds: an integer column), a number's value, a string's text; None when the column is unbound or of
    another type."""
    if term is None:
        return None
    if kind == "iri":
        return term_text(term) if isinstance(term, NamedNode) else None
    if kind == "dateTime":
        return instant_micros(term)
    if kind in ("decimal", "integer"):
        return numeric_value(term)
    return term.value if isinstance(term, Literal) else None


def _sortable_float(number: float) -> str:
    """A float as 16 hex digits whose text order is the numbers' order (IEEE 754 bits, sign-adjusted)."""
    bits = struct.unpack(">Q", struct.pack(">d", number))[0]
    bits = bits ^ 0xFFFFFFFFFFFFFFFF if bits >> 63 else bits | 1 << 63
    return f"{bits:016x}"
