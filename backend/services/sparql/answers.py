"""Running a checked query within the limits, and writing its answer in the format negotiated for it."""

from __future__ import annotations

from collections.abc import Callable

from pyoxigraph import BlankNode, Literal, NamedNode, QueryBoolean, QuerySolutions, RdfFormat, Triple

from segb_server.backend.services.formats import GRAPHS, SOLUTIONS, Format, rdf_bytes
from segb_server.backend.services.sparql.guard import CheckedQuery
from segb_server.backend.services.sparql.limits import QueryLimits
from segb_server.backend.services.sparql.runner import QueryRunner
from segb_server.backend.store.base import QueryResult
from segb_server.backend.vocabulary import PREFIXES

QueryOutput = QueryResult | list[Triple]  # what a limited run hands over to be written out

EX = "http://example.org/"
RDF_TYPE = NamedNode(PREFIXES["rdf"] + "type")
RESULT = NamedNode(EX + "Result")
XSD_BOOLEAN = NamedNode(PREFIXES["xsd"] + "boolean")


def formats_for(form: str) -> tuple[Format, ...]:
    """What a query of `form` can be answered as: solutions for SELECT and ASK, graphs otherwise."""
    return SOLUTIONS if form in ("select", "ask") else GRAPHS


def run_and_write(
    runner: QueryRunner, checked: CheckedQuery, limits: QueryLimits, write: Callable[[QueryOutput], bytes]
) -> tuple[bytes, bool]:
    """The query's answer written out, and whether it was cut at the row cap.

    Only bytes leave this frame: pyoxigraph results must be dropped on the thread that made them, and the
    caller's frame can outlive the call (the SPARQL parser's cache keeps exceptions whose tracebacks reach
    it), which would let the garbage collector drop them on another thread later."""
    answer = runner.run(checked.text, limits)
    return write(answer.result), answer.truncated


def write_in(fmt: Format) -> Callable[[QueryOutput], bytes]:
    """A writer of answers in `fmt` (solutions or a graph, as the format is)."""

    def write(result: QueryOutput) -> bytes:
        if isinstance(result, QuerySolutions | QueryBoolean):
            written = result.serialize(format=fmt.results)
            assert written is not None  # without an output file, pyoxigraph returns the bytes
            return written
        assert fmt.rdf is not None, "a graph is written in an RDF format"
        prefixes = PREFIXES if fmt.rdf in (RdfFormat.TURTLE, RdfFormat.RDF_XML) else None
        return rdf_bytes(result, fmt.rdf, prefixes)

    return write


def rows_as_turtle(result: QueryOutput) -> bytes:
    """The reference's encoding of an answer as Turtle, which its web UI parses: each SELECT row is a blank
    node typed ex:Result with one `ex:<variable>` triple per bound variable. Rows are written in the
    answer's order, so a client reading the document in order keeps ORDER BY; literals keep their datatype
    and language. An ASK answer is one ex:Result with `ex:boolean`."""
    if isinstance(result, QueryBoolean):
        row = BlankNode()
        triples = [
            Triple(row, RDF_TYPE, RESULT),
            Triple(row, NamedNode(EX + "boolean"), Literal(str(bool(result)).lower(), datatype=XSD_BOOLEAN)),
        ]
    elif isinstance(result, QuerySolutions):
        predicates = {var.value: NamedNode(EX + var.value) for var in result.variables}
        triples = []
        for solution in result:
            row = BlankNode()
            triples.append(Triple(row, RDF_TYPE, RESULT))
            for name, predicate in predicates.items():
                value = solution[name]
                if value is not None:
                    triples.append(Triple(row, predicate, value))
    else:
        triples = list(result)
    return rdf_bytes(triples, RdfFormat.TURTLE, {**PREFIXES, "ex": EX})
