"""RDF terms as plain JSON values, the same whichever store answered.

Stores write the same value differently (Virtuoso drops `+00:00` for `Z`, widens `xsd:float` to its binary
value, ...), so values are normalised by datatype: times become UTC ISO 8601 with `Z`, numbers become
numbers (`xsd:float` rounded to the 7 significant digits it holds), IRIs and strings become strings.
"""

from __future__ import annotations

from datetime import UTC, datetime

from pyoxigraph import BlankNode, Literal, NamedNode, Triple

from segb_server.backend.store.terms import term_text

XSD = "http://www.w3.org/2001/XMLSchema#"
_INTEGERS = {
    XSD + name
    for name in (
        "integer", "long", "int", "short", "byte", "nonNegativeInteger", "positiveInteger",
        "nonPositiveInteger", "negativeInteger", "unsignedLong", "unsignedInt", "unsignedShort", "unsignedByte",
    )
}  # fmt: skip
_DECIMALS = {XSD + "decimal", XSD + "double"}

JsonValue = str | int | float | bool | None


def json_value(term: NamedNode | BlankNode | Literal | Triple | None) -> JsonValue:
    if term is None:
        return None
    if isinstance(term, NamedNode):
        return term.value
    if isinstance(term, BlankNode):
        return f"_:{term.value}"
    if isinstance(term, Triple):  # an RDF 1.2 triple term someone else wrote: shown as its N-Triples text
        return term_text(term)
    datatype = term.datatype.value
    text = term.value
    try:
        if datatype == XSD + "dateTime":
            return iso_time(text)
        if datatype in _INTEGERS:
            return int(text)
        if datatype == XSD + "float":
            return float(f"{float(text):.7g}")
        if datatype in _DECIMALS:
            return float(text)
        if datatype == XSD + "boolean":
            return text in ("true", "1")
    except ValueError:
        pass  # an ill-typed literal is shown as written
    return text


def iso_time(text: str) -> str:
    """`2026-03-10T09:00:05.250000+00:00` → `2026-03-10T09:00:05.25Z` (UTC, no trailing zeros)."""
    moment = datetime.fromisoformat(text.replace("Z", "+00:00"))
    if moment.tzinfo is not None:
        moment = moment.astimezone(UTC)
    stamp = moment.replace(tzinfo=None).isoformat()
    if "." in stamp:
        stamp = stamp.rstrip("0")
    return stamp + ("Z" if moment.tzinfo is not None else "")
