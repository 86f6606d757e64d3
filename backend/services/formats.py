"""Media types, the format tables of every endpoint, and content negotiation: one home for all of them.

Each answer kind offers a list of formats, the first being the default when the client accepts anything:
SPARQL solutions (/sparql SELECT and ASK), SPARQL graphs (CONSTRUCT, DESCRIBE), exports of the events graph
(/events, `segb export`) and report tables (/reports/{name}). A request chooses with `?format=` (a name, an
alias or a media type) or with its Accept header (q-values honoured).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from pyoxigraph import Quad, QueryResultsFormat, RdfFormat, Triple, serialize

from segb_server.backend.services.errors import InvalidParameter, ServiceError


@dataclass(frozen=True)
class Format:
    name: str  # the `?format=` value
    media_type: str
    results: QueryResultsFormat | None = None  # how SPARQL solutions are written
    rdf: RdfFormat | None = None  # how RDF graphs are written
    extension: str = ""
    aliases: tuple[str, ...] = ()  # other `?format=` values and media types that mean this format

    @property
    def content_type(self) -> str:
        return f"{self.media_type}; charset=utf-8" if self.media_type.startswith("text/") else self.media_type


class NotAcceptable(ServiceError):
    """None of the media types the client accepts can be produced."""

    code = "not_acceptable"


SOLUTIONS = (
    Format("json", "application/sparql-results+json", QueryResultsFormat.JSON, aliases=("application/json",)),
    Format("xml", "application/sparql-results+xml", QueryResultsFormat.XML, aliases=("application/xml",)),
    Format("csv", "text/csv", QueryResultsFormat.CSV),
    Format("tsv", "text/tab-separated-values", QueryResultsFormat.TSV),
)
# The aliases are the names stock clients send (SPARQLWrapper: json-ld, rdf+xml, xml and json for graphs, n3).
GRAPHS = (
    Format("turtle", "text/turtle", rdf=RdfFormat.TURTLE, extension="ttl", aliases=("application/turtle", "ttl")),
    Format("ntriples", "application/n-triples", rdf=RdfFormat.N_TRIPLES, extension="nt", aliases=("nt",)),
    Format(
        "jsonld",
        "application/ld+json",
        rdf=RdfFormat.JSON_LD,
        extension="jsonld",
        aliases=("json-ld", "application/x-json+ld", "json"),
    ),
    Format("rdfxml", "application/rdf+xml", rdf=RdfFormat.RDF_XML, extension="rdf", aliases=("rdf+xml", "rdf", "xml")),
    Format("n3", "text/n3", rdf=RdfFormat.N3, extension="n3", aliases=("text/rdf+n3", "application/n3")),
)
EXPORTS = (
    Format("turtle", "text/turtle", rdf=RdfFormat.TURTLE, extension="ttl"),
    Format("ntriples", "application/n-triples", rdf=RdfFormat.N_TRIPLES, extension="nt"),
    Format("nquads", "application/n-quads", rdf=RdfFormat.N_QUADS, extension="nq"),
    Format("jsonld", "application/ld+json", rdf=RdfFormat.JSON_LD, extension="jsonld"),
)
# A person's data (GET /humans/{iri}/export): a page they can read, or RDF.
PERSON_EXPORTS = (
    Format("html", "text/html", extension="html"),
    Format("turtle", "text/turtle", rdf=RdfFormat.TURTLE, extension="ttl"),
    Format("ntriples", "application/n-triples", rdf=RdfFormat.N_TRIPLES, extension="nt"),
    Format("jsonld", "application/ld+json", rdf=RdfFormat.JSON_LD, extension="jsonld"),
)
TABLES = (
    Format("json", "application/json", extension="json"),
    Format("csv", "text/csv", extension="csv"),
)


def names(formats: Sequence[Format]) -> list[str]:
    return [fmt.name for fmt in formats]


def _named(fmt: Format, name: str) -> bool:
    return name in (fmt.name, fmt.media_type, *fmt.aliases)


def by_name(formats: Sequence[Format], name: str) -> Format:
    """The format `name` (a name, alias or media type) stands for; InvalidParameter if none."""
    for fmt in formats:
        if _named(fmt, name):
            return fmt
    raise InvalidParameter("format", f"must be one of {', '.join(names(formats))}")


def accepted_media_types(accept: str) -> list[str]:
    """The media types of an Accept header, most wanted first (ties in header order; q=0 ones left out)."""
    offers = []
    for position, part in enumerate(accept.split(",")):
        media, *params = (piece.strip() for piece in part.split(";"))
        quality = 1.0
        for param in params:
            name, _, value = param.partition("=")
            if name.strip().lower() == "q":
                try:
                    quality = float(value)
                except ValueError:
                    quality = 0.0
        if quality > 0 and media:
            offers.append((-quality, position, media.lower()))
    return [media for _, _, media in sorted(offers)]


def format_hint(
    values: Sequence[str], offered: Sequence[Format], known: Sequence[Format] = (), *, what: str = "this answer"
) -> Format | None:
    """The format `?format=` values ask for, read as a hint the way stock clients send it: a value may be a
    comma-separated list of media types, repeats must agree, and a value naming nothing known is ignored
    (None then: the Accept header decides). A known format of another answer kind is NotAcceptable."""
    wanted: list[Format] = []
    for value in values:
        for token in (part.strip() for part in value.split(",")):
            found = next((fmt for fmt in (*offered, *known) if token and _named(fmt, token)), None)
            if found is not None:
                wanted.append(found)
    distinct = list(dict.fromkeys(wanted))
    if len(distinct) > 1:
        raise InvalidParameter("format", f"the values given ({', '.join(values)}) name different formats")
    if not distinct:
        return None
    if distinct[0] not in offered:
        raise NotAcceptable(f"{what[0].upper()}{what[1:]} cannot be given as {distinct[0].name}.")
    return distinct[0]


def negotiate(
    offered: Sequence[Format], accept: str | None, format_name: str | None = None, *, what: str = "this answer"
) -> Format:
    """The format to answer in: `format_name` when given (InvalidParameter if it names none of `offered`),
    else the first of `offered` the Accept header takes (NotAcceptable if none), else the default."""
    if format_name:
        return by_name(offered, format_name)
    if not accept or not accept.strip():
        return offered[0]
    for media in accepted_media_types(accept):
        for fmt in offered:
            if media in (fmt.media_type, *fmt.aliases, "*/*") or (
                media.endswith("/*") and fmt.media_type.startswith(media[:-1])
            ):
                return fmt
    choices = ", ".join(fmt.media_type for fmt in offered)
    raise NotAcceptable(f"Cannot answer {what} as any of '{accept}'; available: {choices}.")


def rdf_bytes(
    items: Iterable[Triple] | Iterable[Quad], rdf_format: RdfFormat, prefixes: dict[str, str] | None = None
) -> bytes:
    """Triples or quads written in `rdf_format` (pyoxigraph's writer, into memory)."""
    written = serialize(items, format=rdf_format, prefixes=prefixes)
    assert written is not None  # without an output file, pyoxigraph returns the bytes
    return written
