"""Turning a /sparql answer into the cells of the query page's table (IRIs, literals, blank nodes)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pyoxigraph import BlankNode, Literal, NamedNode, RdfFormat, parse

XSD = "http://www.w3.org/2001/XMLSchema#"
XSD_STRING = XSD + "string"
RDF_LANG_STRING = "http://www.w3.org/1999/02/22-rdf-syntax-ns#langString"
# Datatypes whose values read plainly (43, 0.87, true, 2026-03-10T10:00:00Z): shown as the value alone, the
# datatype on hover. Any other datatype is part of what the value means, so it stays on screen.
PLAIN_DATATYPES = frozenset(
    XSD + name
    for name in (
        "integer", "long", "int", "short", "byte", "decimal", "double", "float", "boolean", "dateTime",
        "dateTimeStamp", "date", "time", "nonNegativeInteger", "positiveInteger", "unsignedInt", "unsignedLong",
    )
)  # fmt: skip


@dataclass(frozen=True)
class Cell:
    kind: str  # "uri", "literal", "bnode" or "" (unbound)
    value: str = ""
    language: str = ""
    datatype: str = ""  # only when it says something (not xsd:string or rdf:langString)

    @property
    def plain(self) -> bool:
        """A value that reads as it is (a number, a time, a truth value); its datatype goes in a tooltip."""
        return self.datatype in PLAIN_DATATYPES


@dataclass(frozen=True)
class Table:
    columns: list[str]
    rows: list[list[Cell]]
    boolean: bool | None = None  # an ASK answer


def from_results_json(document: dict[str, Any]) -> Table:
    """A SPARQL JSON results document (SELECT or ASK)."""
    if "boolean" in document:
        return Table(columns=[], rows=[], boolean=bool(document["boolean"]))
    columns = list(document["head"].get("vars", []))
    rows = [[_json_cell(binding.get(name)) for name in columns] for binding in document["results"]["bindings"]]
    return Table(columns=columns, rows=rows)


def from_ntriples(body: bytes) -> Table:
    """A CONSTRUCT or DESCRIBE answer, one row per triple."""
    rows = [
        [_term_cell(quad.subject), _term_cell(quad.predicate), _term_cell(quad.object)]
        for quad in parse(body, RdfFormat.N_TRIPLES)
    ]
    return Table(columns=["subject", "predicate", "object"], rows=rows)


def _json_cell(term: dict[str, str] | None) -> Cell:
    if term is None:
        return Cell("")
    kind = "literal" if term["type"] in ("literal", "typed-literal") else term["type"]
    datatype = term.get("datatype", "")
    return Cell(
        kind, term["value"], term.get("xml:lang", ""), "" if datatype in (XSD_STRING, RDF_LANG_STRING) else datatype
    )


def _term_cell(term: object) -> Cell:
    if isinstance(term, NamedNode):
        return Cell("uri", term.value)
    if isinstance(term, BlankNode):
        return Cell("bnode", term.value)
    if isinstance(term, Literal):
        datatype = term.datatype.value
        return Cell(
            "literal", term.value, term.language or "", "" if datatype in (XSD_STRING, RDF_LANG_STRING) else datatype
        )
    return Cell("literal", str(term))
