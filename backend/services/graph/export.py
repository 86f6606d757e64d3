"""Streaming the events graph out in an RDF syntax, a batch at a time, never holding it all in memory."""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from itertools import chain

from pyoxigraph import NamedNode, Quad, RdfFormat, Triple, parse

from segb_server.backend.services.formats import Format, rdf_bytes
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.store.base import Store
from segb_server.backend.vocabulary import PREFIXES

BATCH_TRIPLES = 10_000
logger = logging.getLogger("segb.export")


def stream_graph(store: Store, fmt: Format) -> Iterator[bytes]:
    """The events graph as the store holds it, in `fmt`. The first batch is read here, before any byte is
    written, so a store that does not answer is an error the caller can still turn into a status (blocking:
    call it off the event loop)."""
    batches = ([quad.triple for quad in batch] for batch in store.batches(BATCH_TRIPLES))
    first = next(batches, None)
    return write_graph(chain([] if first is None else [first], batches), fmt, NamedNode(store.graph_uri))


def stream_received(journal: Journal, fmt: Format, graph_uri: str) -> Iterator[bytes]:
    """The events graph as robots sent it: the journal's content since the last clearing. N-Triples and
    N-Quads are the journal's own bytes; other syntaxes are written from them."""
    documents = journal.received_documents()
    if fmt.rdf == RdfFormat.N_TRIPLES:
        return documents
    if fmt.rdf == RdfFormat.N_QUADS:
        suffix = f" <{graph_uri}> .\n".encode()
        return (document.replace(b" .\n", suffix) for document in documents)
    batches = ([quad.triple for quad in parse(document, RdfFormat.N_TRIPLES)] for document in documents)
    return write_graph(batches, fmt, NamedNode(graph_uri))


def write_graph(batches: Iterable[list[Triple]], fmt: Format, graph: NamedNode) -> Iterator[bytes]:
    """Batches of triples written as one document in `fmt`: N-Quads name `graph`, Turtle declares the prefixes
    once, JSON-LD is one array. JSON-LD 1.1 cannot carry RDF 1.2 triple terms: triples holding one are left
    out of a JSON-LD export (and logged), so the document stays whole."""
    assert fmt.rdf is not None, "an export format writes RDF"
    header = "".join(f"@prefix {name}: <{iri}> .\n" for name, iri in sorted(PREFIXES.items())).encode()
    if fmt.rdf == RdfFormat.TURTLE:
        yield header
    elif fmt.rdf == RdfFormat.JSON_LD:
        yield b"["
    first, left_out = True, 0
    for triples in batches:
        if fmt.rdf == RdfFormat.N_QUADS:
            yield rdf_bytes([Quad(t.subject, t.predicate, t.object, graph) for t in triples], fmt.rdf)
        elif fmt.rdf == RdfFormat.TURTLE:
            yield _without_prefixes(rdf_bytes(triples, fmt.rdf, PREFIXES))
        elif fmt.rdf == RdfFormat.JSON_LD:
            plain = [t for t in triples if not isinstance(t.subject, Triple) and not isinstance(t.object, Triple)]
            left_out += len(triples) - len(plain)
            nodes = rdf_bytes(plain, fmt.rdf).strip()[1:-1] if plain else b""
            if nodes:
                yield (b"" if first else b",") + nodes
                first = False
        else:
            yield rdf_bytes(triples, fmt.rdf)
    if fmt.rdf == RdfFormat.JSON_LD:
        yield b"]"
    if left_out:
        logger.warning("JSON-LD export left out %d triples holding RDF 1.2 triple terms", left_out)


def _without_prefixes(turtle: bytes) -> bytes:
    """A batch's Turtle without the `@prefix` lines the writer puts first (in an order of its own): the document's
    header declared them once already."""
    start = 0
    while turtle.startswith(b"@prefix ", start):
        start = turtle.index(b"\n", start) + 1
    return turtle[start:]
