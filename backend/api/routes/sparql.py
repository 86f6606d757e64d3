"""Read-only SPARQL over the events graph: the SPARQL 1.1 Protocol at /sparql, and the reference backend's
/query and /query/validate for the clients written against it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import parse_qs

from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, Field
from pyoxigraph import (
    BlankNode,
    Literal,
    NamedNode,
    QueryBoolean,
    QueryResultsFormat,
    QuerySolutions,
    RdfFormat,
    Triple,
    serialize,
)

from segb_server.backend.api.deps import Auditor, LimitedBody, ServicesDep
from segb_server.backend.services.container import Services
from segb_server.backend.services.errors import InvalidParameter, ServiceError, UnsupportedMediaType
from segb_server.backend.services.export import NotAcceptable
from segb_server.backend.services.media_types import accepted_media_types
from segb_server.backend.services.namespaces import PREFIXES
from segb_server.backend.services.sparql_guard import MAX_QUERY_BYTES, CheckedQuery, guard_query, query_rejected
from segb_server.backend.services.sparql_limits import LimitedResult, QueryLimits, run_limited
from segb_server.backend.store.base import QueryResult, Store

router = APIRouter(tags=["sparql"])

QueryOutput = QueryResult | list[Triple]  # what a limited run hands over to be written out


@dataclass(frozen=True)
class ResultFormat:
    name: str  # the `?format=` value
    media_type: str
    results: QueryResultsFormat | None = None  # how SELECT and ASK answers are written
    rdf: RdfFormat | None = None  # how CONSTRUCT and DESCRIBE answers are written


# The first of each list is the default when the client accepts anything.
SOLUTION_FORMATS = [
    ResultFormat("json", "application/sparql-results+json", results=QueryResultsFormat.JSON),
    ResultFormat("xml", "application/sparql-results+xml", results=QueryResultsFormat.XML),
    ResultFormat("csv", "text/csv", results=QueryResultsFormat.CSV),
    ResultFormat("tsv", "text/tab-separated-values", results=QueryResultsFormat.TSV),
]
GRAPH_FORMATS = [
    ResultFormat("turtle", "text/turtle", rdf=RdfFormat.TURTLE),
    ResultFormat("ntriples", "application/n-triples", rdf=RdfFormat.N_TRIPLES),
    ResultFormat("jsonld", "application/ld+json", rdf=RdfFormat.JSON_LD),
    ResultFormat("rdfxml", "application/rdf+xml", rdf=RdfFormat.RDF_XML),
]
# Generic types that clients send for the same documents.
ALIASES = {"application/json": "application/sparql-results+json", "application/xml": "application/sparql-results+xml"}
FORMAT_NAMES = ", ".join(fmt.name for fmt in SOLUTION_FORMATS + GRAPH_FORMATS)


def negotiate(form: str, accept: str | None, format_name: str | None) -> ResultFormat:
    """The result format for a query of `form`: `?format=` (a name or a media type) wins over Accept.

    Raise InvalidParameter for an unknown `format`, NotAcceptable when nothing acceptable fits the form."""
    offered = SOLUTION_FORMATS if form in ("select", "ask") else GRAPH_FORMATS
    by_key = {key: fmt for fmt in SOLUTION_FORMATS + GRAPH_FORMATS for key in (fmt.name, fmt.media_type)}
    if format_name:
        wanted = by_key.get(ALIASES.get(format_name, format_name))
        if wanted is None:
            raise InvalidParameter("format", f"must be one of {FORMAT_NAMES}")
        if wanted not in offered:
            raise NotAcceptable(f"A {form.upper()} query cannot be answered as {wanted.name}.")
        return wanted
    if not accept or not accept.strip():
        return offered[0]
    for media in accepted_media_types(accept):
        media = ALIASES.get(media, media)
        for fmt in offered:
            if media in (fmt.media_type, "*/*") or (media.endswith("/*") and fmt.media_type.startswith(media[:-1])):
                return fmt
    choices = ", ".join(fmt.media_type for fmt in offered)
    raise NotAcceptable(f"Cannot answer a {form.upper()} query as any of '{accept}'; available: {choices}.")


def _results_bytes(result: QueryOutput, fmt: ResultFormat) -> bytes:
    if isinstance(result, QuerySolutions | QueryBoolean):
        return result.serialize(format=fmt.results)  # type: ignore[return-value]
    prefixes = PREFIXES if fmt.rdf in (RdfFormat.TURTLE, RdfFormat.RDF_XML) else None
    return serialize(result, format=fmt.rdf, prefixes=prefixes)  # type: ignore[return-value]


def run_checked(services: Services, checked: CheckedQuery) -> LimitedResult:
    """Run a query the guard has checked (the text sent is the text checked), within the configured limits."""
    settings = services.settings
    limits = QueryLimits(settings.sparql_timeout_seconds, settings.sparql_max_rows)
    return run_limited(services.store, checked.text, limits)


def run_and_write(
    services: Services, checked: CheckedQuery, write: Callable[[QueryOutput], bytes]
) -> tuple[bytes, bool]:
    """The query's answer written out, and whether it was cut at the row cap.

    Only bytes leave this frame: pyoxigraph results must be dropped on the thread that made them, and the
    caller's frame can outlive the call (the SPARQL parser's cache keeps exceptions whose tracebacks reach
    it), which would let the garbage collector drop them on another thread later."""
    answer = run_checked(services, checked)
    return write(answer.result), answer.truncated


def limit_headers(truncated: bool, services: Services) -> dict[str, str]:
    """Headers telling a client the answer was cut at the row cap (standard clients ignore them)."""
    if not truncated:
        return {}
    return {"X-SEGB-Truncated": "true", "X-SEGB-Max-Rows": str(services.settings.sparql_max_rows)}


def _content_type(media_type: str) -> str:
    return f"{media_type}; charset=utf-8" if media_type.startswith("text/") else media_type


def _check_dataset(store: Store, default_graphs: list[str], named_graphs: list[str]) -> None:
    """The protocol's dataset parameters may only restate the fixed dataset (the events graph as default)."""
    if named_graphs or any(graph != store.graph_uri for graph in default_graphs):
        raise query_rejected(
            "dataset",
            f"The dataset is fixed: the events graph <{store.graph_uri}> is the default graph and there are no "
            "named graphs, so 'default-graph-uri' may only name it and 'named-graph-uri' is not supported.",
        )


@dataclass(frozen=True)
class ProtocolRequest:
    """One SPARQL Protocol query request, however it arrived (GET, POST form, POST body)."""

    query: str
    format: str | None
    default_graphs: list[str]
    named_graphs: list[str]


def _single(values: list[str], name: str) -> str | None:
    if len(values) > 1:
        raise InvalidParameter(name, "must be given once")
    return values[0] if values else None


def _from_fields(fields: dict[str, list[str]]) -> ProtocolRequest:
    if "update" in fields:
        raise query_rejected("update", "SPARQL Update is not allowed: this endpoint is read-only.", query_kind="update")
    query = _single(fields.get("query", []), "query")
    if query is None:
        raise query_rejected("empty", "The 'query' parameter is missing.")
    return ProtocolRequest(
        query=query,
        format=_single(fields.get("format", []), "format"),
        default_graphs=fields.get("default-graph-uri", []),
        named_graphs=fields.get("named-graph-uri", []),
    )


async def _answer(services: Services, request: ProtocolRequest, accept: str | None) -> Response:
    store = services.store

    def work() -> tuple[bytes, bool, ResultFormat]:
        _check_dataset(store, request.default_graphs, request.named_graphs)
        checked = guard_query(request.query, store.graph_uri)
        # Negotiate before running, so an unacceptable request costs no query.
        fmt = negotiate(checked.form, accept, request.format)
        return (*run_and_write(services, checked, lambda result: _results_bytes(result, fmt)), fmt)

    # Checking (rdflib parsing) and the query itself are blocking work.
    body, truncated, fmt = await run_in_threadpool(work)
    headers = {"Vary": "Accept", **limit_headers(truncated, services)}
    return Response(body, media_type=_content_type(fmt.media_type), headers=headers)


_PROTOCOL_DESCRIPTION = (
    "Read-only [SPARQL 1.1 Protocol](https://www.w3.org/TR/sparql11-protocol/) endpoint over the events graph, "
    "which is every query's default graph (there are no named graphs). SELECT and ASK answer "
    "`application/sparql-results+json` (default), `application/sparql-results+xml`, `text/csv` or "
    "`text/tab-separated-values`; CONSTRUCT and DESCRIBE answer `text/turtle` (default), "
    "`application/n-triples`, `application/ld+json` or `application/rdf+xml`. Chosen by `Accept`, or by "
    f"`?format=` ({FORMAT_NAMES}); 406 when nothing acceptable fits the query form.\n\n"
    "Rejected with 400 and a `reason`: SPARQL Update (`update`), `SERVICE` (`service`), Virtuoso `DEFINE` pragmas "
    "(`virtuoso_pragma`), `bif:`/`sql:` and other OpenLink extensions (`virtuoso_extension`), functions called "
    "by IRI outside XSD and XPath (`extension_function`), `FROM`/`FROM NAMED`/dataset parameters naming anything "
    "but the events graph (`dataset`), `GRAPH` patterns (`graph`), undeclared prefixes (`undeclared_prefix`) and "
    f"syntax errors (`syntax`, with `line` and `column`). Queries over {MAX_QUERY_BYTES} bytes get 413.\n\n"
    "Limits: an answer holds at most `SPARQL_MAX_ROWS` rows (or triples); a longer one is cut there and carries "
    "`X-SEGB-Truncated: true`. A query still running after `SPARQL_TIMEOUT_SECONDS` is stopped: 503 with "
    "`error: query_timeout`."
)


@router.get("/sparql", summary="SPARQL query (GET)", description=_PROTOCOL_DESCRIPTION, response_class=Response)
async def sparql_get(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    query: str | None = Query(None, description="The SPARQL query (SELECT, ASK, CONSTRUCT or DESCRIBE)."),
    format: str | None = Query(None, description=f"{FORMAT_NAMES}, or a media type; overrides Accept."),
    default_graph_uri: list[str] = Query([], alias="default-graph-uri", description="Only the events graph."),
    named_graph_uri: list[str] = Query([], alias="named-graph-uri", description="Not supported."),
) -> Response:
    fields = {"default-graph-uri": default_graph_uri, "named-graph-uri": named_graph_uri}
    fields.update({name: [value] for name, value in (("query", query), ("format", format)) if value is not None})
    return await _answer(services, _from_fields(fields), request.headers.get("accept"))


_POST_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/sparql-query": {
                "schema": {"type": "string"},
                "example": "SELECT * WHERE { ?s ?p ?o } LIMIT 10",
            },
            "application/x-www-form-urlencoded": {
                "schema": {
                    "type": "object",
                    "properties": {
                        "query": {"type": "string"},
                        "format": {"type": "string"},
                        "default-graph-uri": {"type": "string"},
                    },
                    "required": ["query"],
                }
            },
        },
    }
}


@router.post(
    "/sparql",
    summary="SPARQL query (POST)",
    description=_PROTOCOL_DESCRIPTION
    + "\n\nThe body is the query (`application/sparql-query`) or a form (`application/x-www-form-urlencoded`, "
    "field `query`); other types get 415.",
    openapi_extra=_POST_BODY,
    response_class=Response,
)
async def sparql_post(request: Request, principal: Auditor, services: ServicesDep, body: LimitedBody) -> Response:
    media_type = (request.headers.get("content-type") or "").split(";")[0].strip().lower()
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as error:
        raise query_rejected("syntax", f"The body is not UTF-8: {error}.") from None
    # Dataset and format parameters may also come in the query string (the protocol puts them there for
    # application/sparql-query bodies).
    fields = {key: request.query_params.getlist(key) for key in request.query_params}
    if media_type == "application/sparql-query":
        fields["query"] = [text]
    elif media_type == "application/x-www-form-urlencoded":
        for key, values in parse_qs(text, keep_blank_values=True).items():
            fields[key] = fields.get(key, []) + values
    else:
        raise UnsupportedMediaType(
            f"Send the query as application/sparql-query or application/x-www-form-urlencoded, not "
            f"'{media_type or 'no Content-Type'}'."
        )
    return await _answer(services, _from_fields(fields), request.headers.get("accept"))


# --- the reference backend's /query and /query/validate ---------------------------------------------------

EX = "http://example.org/"
RDF_TYPE = NamedNode("http://www.w3.org/1999/02/22-rdf-syntax-ns#type")
RESULT = NamedNode(EX + "Result")
XSD_BOOLEAN = NamedNode("http://www.w3.org/2001/XMLSchema#boolean")


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
    return serialize(triples, format=RdfFormat.TURTLE, prefixes={**PREFIXES, "ex": EX})  # type: ignore[return-value]


@router.get(
    "/query",
    summary="SPARQL query, reference format",
    description=(
        "Compatible with the reference backend's `GET /query?query=…`: answers `text/turtle` whatever the query "
        "form. SELECT rows are encoded as RDF: each row is a blank node typed `<http://example.org/Result>` "
        "with one `<http://example.org/{variable}>` triple per bound variable (unbound ones are left out), "
        "written in the answer's order; literals keep their datatype and language. ASK gives one such node "
        "with `<http://example.org/boolean>`; CONSTRUCT and DESCRIBE give their triples. The same checks as "
        "`/sparql` apply, and a rejected query is a 400 whose `detail` is the reason (the reference answered "
        "422). New clients should use `/sparql`, which speaks the standard result formats."
    ),
    response_class=Response,
    responses={200: {"content": {"text/turtle": {}}}},
)
async def query_reference(
    services: ServicesDep,
    principal: Auditor,
    query: str = Query(..., description="The SPARQL query (SELECT, ASK, CONSTRUCT or DESCRIBE)."),
) -> Response:
    def work() -> tuple[bytes, bool]:
        return run_and_write(services, guard_query(query, services.store.graph_uri), rows_as_turtle)

    body, truncated = await run_in_threadpool(work)
    return Response(body, media_type="text/turtle; charset=utf-8", headers=limit_headers(truncated, services))


class ValidateRequest(BaseModel):
    query: str = Field(description="The SPARQL query to check.")


class QueryValidation(BaseModel):
    valid: bool
    query_kind: str = Field(description="select, construct, ask, describe, update or unknown (as the reference).")
    form: str | None = Field(description="The query form (or `update`); null when it cannot be told.")
    allows_update_execution: bool = Field(False, description="Always false: updates never run through the API.")
    message: str = Field(description="`Valid SPARQL query.` or why the query would be rejected.")
    error: str | None = Field(None, description="Why the query would be rejected; null when valid.")
    reason: str | None = Field(None, description="Machine-readable reason (update, service, syntax…); null when valid.")
    line: int | None = Field(None, description="Line of a syntax error, when known.")
    column: int | None = Field(None, description="Column of a syntax error, when known.")


@router.post(
    "/query/validate",
    summary="Check a SPARQL query without running it",
    description=(
        'Compatible with the reference backend: body `{"query": "…"}`, answer 200 with `valid`, '
        "`query_kind` (select, construct, ask, describe, update or unknown), `allows_update_execution` (always "
        "false) and `message`. Also `form`, `error`, `reason`, `line` and `column`. The checks are exactly "
        "those `/sparql` and `/query` apply before running a query."
    ),
    response_model=QueryValidation,
)
async def validate_query(services: ServicesDep, principal: Auditor, payload: ValidateRequest) -> QueryValidation:
    graph_uri = services.store.graph_uri

    def work() -> QueryValidation:
        try:
            checked: CheckedQuery = guard_query(payload.query, graph_uri)
        except ServiceError as error:
            kind = str(error.details.get("query_kind") or "unknown")
            return QueryValidation(
                valid=False,
                query_kind=kind,
                form=None if kind == "unknown" else kind,
                message=error.message,
                error=error.message,
                reason=error.details.get("reason"),
                line=error.details.get("line"),
                column=error.details.get("column"),
            )
        return QueryValidation(valid=True, query_kind=checked.form, form=checked.form, message="Valid SPARQL query.")

    return await run_in_threadpool(work)
