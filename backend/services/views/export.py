"""Streaming the events graph out in an RDF syntax, a batch at a time, never holding it all in memory."""

from __future__ import annotations

from collections.abc import Iterator

from pyoxigraph import NamedNode, Quad, RdfFormat

from segb_server.backend.services.formats import Format, rdf_bytes
from segb_server.backend.store.base import Store
from segb_server.backend.vocabulary import PREFIXES

BATCH_TRIPLES = 10_000


def stream_graph(store: Store, fmt: Format) -> Iterator[bytes]:
    """The events graph in `fmt`. N-Quads name the events graph; Turtle declares the prefixes once."""
    assert fmt.rdf is not None, "an export format writes RDF"
    graph = NamedNode(store.graph_uri)
    header = "".join(f"@prefix {name}: <{iri}> .\n" for name, iri in sorted(PREFIXES.items())).encode()
    if fmt.rdf == RdfFormat.TURTLE:
        yield header
    elif fmt.rdf == RdfFormat.JSON_LD:
        yield b"["
    first = True
    for batch in store.batches(BATCH_TRIPLES):
        if fmt.rdf == RdfFormat.N_QUADS:
            yield rdf_bytes([Quad(q.subject, q.predicate, q.object, graph) for q in batch], fmt.rdf)
        elif fmt.rdf == RdfFormat.TURTLE:
            text = rdf_bytes([q.triple for q in batch], fmt.rdf, PREFIXES)
            yield text[len(header) :] if text.startswith(header) else text
        elif fmt.rdf == RdfFormat.JSON_LD:
            nodes = rdf_bytes([q.triple for q in batch], fmt.rdf).strip()[1:-1]
            if nodes:
                yield (b"" if first else b",") + nodes
                first = False
        else:
            yield rdf_bytes([q.triple for q in batch], fmt.rdf)
    if fmt.rdf == RdfFormat.JSON_LD:
        yield b"]"
