"""Streaming the events graph out in an RDF syntax, a batch at a time, never holding it all in memory."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from pyoxigraph import NamedNode, Quad, RdfFormat, serialize

from segb_server.backend.services.errors import ServiceError
from segb_server.backend.services.media_types import accepted_media_types
from segb_server.backend.services.namespaces import PREFIXES
from segb_server.backend.store.base import Store

BATCH_TRIPLES = 10_000


@dataclass(frozen=True)
class ExportFormat:
    media_type: str
    rdf_format: RdfFormat
    extension: str


EXPORT_FORMATS = {
    fmt.media_type: fmt
    for fmt in (
        ExportFormat("text/turtle", RdfFormat.TURTLE, "ttl"),
        ExportFormat("application/n-triples", RdfFormat.N_TRIPLES, "nt"),
        ExportFormat("application/n-quads", RdfFormat.N_QUADS, "nq"),
        ExportFormat("application/ld+json", RdfFormat.JSON_LD, "jsonld"),
    )
}
FORMAT_NAMES = {
    "turtle": "text/turtle",
    "ntriples": "application/n-triples",
    "nquads": "application/n-quads",
    "jsonld": "application/ld+json",
}


class NotAcceptable(ServiceError):
    """None of the media types the client accepts can be produced."""

    code = "not_acceptable"


def negotiate(accept: str | None) -> ExportFormat:
    """Pick the export format from an Accept header (q-values honoured; Turtle when anything goes)."""
    if not accept or not accept.strip():
        return EXPORT_FORMATS["text/turtle"]
    for media in accepted_media_types(accept):
        if media in EXPORT_FORMATS:
            return EXPORT_FORMATS[media]
        if media in ("*/*", "text/*", "application/*"):
            return EXPORT_FORMATS["text/turtle"]
    raise NotAcceptable(f"Cannot produce any of '{accept}'; available: {', '.join(EXPORT_FORMATS)}.")


def stream_graph(store: Store, fmt: ExportFormat) -> Iterator[bytes]:
    """The events graph in `fmt`. N-Quads name the events graph; Turtle declares the prefixes once."""
    graph = NamedNode(store.graph_uri)
    header = "".join(f"@prefix {name}: <{iri}> .\n" for name, iri in sorted(PREFIXES.items())).encode()
    if fmt.rdf_format == RdfFormat.TURTLE:
        yield header
    elif fmt.rdf_format == RdfFormat.JSON_LD:
        yield b"["
    first = True
    for batch in store.batches(BATCH_TRIPLES):
        if fmt.rdf_format == RdfFormat.N_QUADS:
            yield serialize([Quad(q.subject, q.predicate, q.object, graph) for q in batch], format=fmt.rdf_format)
        elif fmt.rdf_format == RdfFormat.TURTLE:
            text = serialize([q.triple for q in batch], format=fmt.rdf_format, prefixes=PREFIXES)
            yield text[len(header) :] if text.startswith(header) else text
        elif fmt.rdf_format == RdfFormat.JSON_LD:
            nodes = serialize([q.triple for q in batch], format=fmt.rdf_format).strip()[1:-1]
            if nodes:
                yield (b"" if first else b",") + nodes
                first = False
        else:
            yield serialize([q.triple for q in batch], format=fmt.rdf_format)
    if fmt.rdf_format == RdfFormat.JSON_LD:
        yield b"]"
