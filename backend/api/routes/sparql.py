"""Read-only SPARQL over the events graph: the SPARQL 1.1 Protocol at /sparql, and the reference backend's
/query and /query/validate for the clients written against it."""

from __future__ import annotations

from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Auditor, LimitedBody, ServicesDep
from segb_server.backend.api.errors import ReferenceQueryRefused
from segb_server.backend.api.sparql_protocol import ProtocolRequest, from_get, from_post
from segb_server.backend.services.container import Services
from segb_server.backend.services.csv_cells import spreadsheet_safe_answer
from segb_server.backend.services.errors import InvalidQuery, ServiceError
from segb_server.backend.services.formats import GRAPHS, SOLUTIONS, Format, format_hint, names, negotiate
from segb_server.backend.services.sparql.answers import formats_for, rows_as_turtle, run_and_write, write_in
from segb_server.backend.services.sparql.checkers import guard_user_query
from segb_server.backend.services.sparql.guard import MAX_QUERY_BYTES, MAX_QUERY_TERMS, CheckedQuery
from segb_server.backend.services.sparql.limits import QueryLimits
from segb_server.backend.services.text import UnicodeModel

router = APIRouter(tags=["sparql"])

FORMAT_NAMES = ", ".join(names(SOLUTIONS + GRAPHS))


def limits_of(services: Services) -> QueryLimits:
    settings = services.settings
    return QueryLimits(settings.sparql_timeout_seconds, settings.sparql_max_rows)


def limit_headers(truncated: bool, services: Services) -> dict[str, str]:
    """Headers telling a client the answer was cut at the row cap (standard clients ignore them)."""
    if not truncated:
        return {}
    return {"X-SEGB-Truncated": "true", "X-SEGB-Max-Rows": str(services.settings.sparql_max_rows)}


def _choose(checked: CheckedQuery, request: ProtocolRequest, accept: str | None) -> Format:
    offered = formats_for(checked.form)
    what = f"a {checked.form.upper()} query"
    hinted = format_hint(request.formats, offered, SOLUTIONS + GRAPHS, what=what)
    return hinted or negotiate(offered, accept, what=what)


async def _answer(services: Services, request: ProtocolRequest, accept: str | None) -> Response:
    store = services.store

    def work() -> tuple[bytes, bool, Format]:
        request.check_dataset(store.graph_uri)
        limits = limits_of(services)  # checking the query counts against its time limit
        checked = guard_user_query(request.query, store.graph_uri, limits)
        fmt = _choose(checked, request, accept)  # before running: an unacceptable request costs no query
        body, truncated = run_and_write(services.queries, checked, limits, write_in(fmt))
        return spreadsheet_safe_answer(body, fmt.media_type), truncated, fmt

    # Checking (rdflib parsing) and the query itself are blocking work.
    body, truncated, fmt = await run_in_threadpool(work)
    headers = {"Vary": "Accept", **limit_headers(truncated, services)}
    return Response(body, media_type=fmt.content_type, headers=headers)


_PROTOCOL_DESCRIPTION = (
    "Read-only [SPARQL 1.1 Protocol](https://www.w3.org/TR/sparql11-protocol/) endpoint over the events graph, "
    "which is every query's default graph (there are no named graphs). SELECT and ASK answer "
    "`application/sparql-results+json` (default), `application/sparql-results+xml`, `text/csv` or "
    "`text/tab-separated-values` (in CSV and TSV, a text a spreadsheet would run as a formula, such as "
    "`=HYPERLINK(…)`, starts with an apostrophe, as in the reports' CSV); CONSTRUCT and DESCRIBE answer "
    "`text/turtle` (default), `application/n-triples`, `application/ld+json`, `application/rdf+xml` or "
    "`text/n3`. Chosen by `Accept`, or "
    f"by `?format=` ({FORMAT_NAMES}, or a media type), read as a hint as stock clients send it: repeats must agree, "
    "a value naming no format is ignored (then `Accept` decides), and `xml` or `json` ask for RDF/XML or JSON-LD "
    "when the answer is a graph. 406 when nothing acceptable fits the query form.\n\n"
    "Rejected with 400 and a `reason`: SPARQL Update (`update`), `SERVICE` (`service`), Virtuoso `DEFINE` pragmas "
    "(`virtuoso_pragma`), `bif:`/`sql:` and other OpenLink extensions (`virtuoso_extension`), functions called "
    "by IRI outside XSD and XPath (`extension_function`), `FROM`/`FROM NAMED`/dataset parameters naming anything "
    "but the events graph (`dataset`), `GRAPH` patterns (`graph`), undeclared prefixes (`undeclared_prefix`), "
    "`query` given more than once (`multiple_queries`) and "
    f"syntax errors (`syntax`, with `line` and `column`). Queries over {MAX_QUERY_BYTES} bytes (`too_long`) or "
    f"with more than {MAX_QUERY_TERMS} operators, commas and brackets (`too_complex`) get 413.\n\n"
    "Limits: an answer holds at most `SPARQL_MAX_ROWS` rows (or triples); a longer one is cut there and carries "
    "`X-SEGB-Truncated: true`. A query still being checked or running after `SPARQL_TIMEOUT_SECONDS` is "
    "stopped: 503 with `error: query_timeout`."
)


@router.get("/sparql", summary="SPARQL query (GET)", description=_PROTOCOL_DESCRIPTION, response_class=Response)
async def sparql_get(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    query: str | None = Query(None, description="The SPARQL query (SELECT, ASK, CONSTRUCT or DESCRIBE)."),
    format: list[str] = Query([], description=f"{FORMAT_NAMES}, or a media type; a hint over Accept."),
    default_graph_uri: list[str] = Query([], alias="default-graph-uri", description="Only the events graph."),
    named_graph_uri: list[str] = Query([], alias="named-graph-uri", description="Not supported."),
) -> Response:
    # The declared parameters document the endpoint; the request is read whole, so repeats are seen.
    return await _answer(services, from_get(request), request.headers.get("accept"))


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
    return await _answer(services, from_post(request, body), request.headers.get("accept"))


# --- the reference backend's /query and /query/validate ---------------------------------------------------


@router.get(
    "/query",
    summary="SPARQL query, reference format",
    description=(
        "Compatible with the reference backend's `GET /query?query=…`: answers `text/turtle` whatever the query "
        "form. SELECT rows are encoded as RDF: each row is a blank node typed `<http://example.org/Result>` "
        "with one `<http://example.org/{variable}>` triple per bound variable (unbound ones are left out), "
        "written in the answer's order; literals keep their datatype and language. ASK gives one such node "
        "with `<http://example.org/boolean>`; CONSTRUCT and DESCRIBE give their triples. The same checks as "
        "`/sparql` apply, and a rejected query is a 422 whose `detail` is the reason, as the reference answers. "
        "New clients should use `/sparql`, which speaks the standard result formats."
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
        limits = limits_of(services)
        try:
            checked = guard_user_query(query, services.store.graph_uri, limits)
        except InvalidQuery as refused:
            raise ReferenceQueryRefused(refused.message, **refused.details) from None
        return run_and_write(services.queries, checked, limits, rows_as_turtle)

    body, truncated = await run_in_threadpool(work)
    return Response(body, media_type="text/turtle; charset=utf-8", headers=limit_headers(truncated, services))


class ValidateRequest(UnicodeModel):
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
            checked: CheckedQuery = guard_user_query(payload.query, graph_uri, limits_of(services))
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
