"""Parsing RDF payloads with pyoxigraph, turning parser failures into errors that name the position."""

from __future__ import annotations

from itertools import islice

from pyoxigraph import Quad, RdfFormat, Triple, parse

from segb_server.backend.services.errors import InvalidRdf, PayloadTooLarge
from segb_server.backend.services.ingest.skolem import might_contain_blank_nodes, skolemize
from segb_server.backend.store.terms import term_text

SYNTAX_NAMES = {RdfFormat.TURTLE: "Turtle", RdfFormat.N_TRIPLES: "N-Triples"}
UTF8_BYTE_ORDER_MARK = b"\xef\xbb\xbf"


def skolemized(data: bytes, quads: list[Quad], skolem_base: str) -> list[Quad]:
    """The quads with their blank nodes skolemised (`data` is their text, to skip the work when it has none)."""
    return skolemize(quads, skolem_base) if might_contain_blank_nodes(data) else quads


def parse_quads(data: bytes, rdf_format: RdfFormat, *, max_triples: int) -> list[Quad]:
    """All triples of the document as parsed, in the default graph, blank nodes as they came.

    pyoxigraph parses about 25 times faster than rdflib here, which is what keeps re-publishing a
    client's whole accumulated graph cheap. Relative IRIs are refused (no base IRI is assumed), rather
    than resolved against some server path as the reference did.
    """
    data = data.removeprefix(UTF8_BYTE_ORDER_MARK)  # what some editors start a UTF-8 file with: not the document's
    try:
        quads = list(islice(parse(data, rdf_format), max_triples + 1))
    except SyntaxError as error:
        raise invalid_rdf(error, rdf_format) from None
    except MemoryError as error:  # pyoxigraph's parser holds one token (a literal, an IRI) in a bounded buffer
        raise PayloadTooLarge(f"A single literal or IRI is too long for the RDF parser ({error}).") from None
    if len(quads) > max_triples:
        raise PayloadTooLarge(f"The payload has more than {max_triples} triples (MAX_TRIPLES_PER_POST).")
    refuse_triple_terms(quads, rdf_format)
    return quads


def refuse_triple_terms(quads: list[Quad], rdf_format: RdfFormat) -> None:
    """RDF 1.2 triple terms (`<<( s p o )>>`) are refused on every store: Virtuoso cannot hold them and JSON-LD
    cannot export them, so accepting them on one store would make the others disagree."""
    for index, quad in enumerate(quads, start=1):
        if isinstance(quad.subject, Triple) or isinstance(quad.object, Triple):
            syntax = SYNTAX_NAMES.get(rdf_format, rdf_format.name)
            raise InvalidRdf(
                f"triple {index} holds an RDF 1.2 triple term ({term_text(quad.object)}); triple terms are not "
                "accepted by this server",
                syntax=syntax,
            )


def invalid_rdf(error: SyntaxError, rdf_format: RdfFormat) -> InvalidRdf:
    """The service error for a pyoxigraph parse failure, keeping its line and column."""
    message = str(error.msg or error).split(": ", 1)[-1]
    if "No scheme found" in message:
        message += " (relative IRIs are not accepted: write absolute IRIs or declare @base)"
    syntax = SYNTAX_NAMES.get(rdf_format, rdf_format.name)
    return InvalidRdf(message, syntax=syntax, line=error.lineno, column=error.offset)
