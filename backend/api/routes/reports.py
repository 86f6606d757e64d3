"""GET /reports and GET /reports/{name}: the audit reports as JSON or CSV, one documented route per report.

The catalog is the one source of a report's parameters: each `.rq` file's header becomes its route's OpenAPI
parameters, the `parameters` of its JSON answer (from which the UI builds its filter form), and the checks
applied to a request. Adding a filter to a `.rq` file touches no Python.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.paging import MAX_OFFSET
from segb_server.backend.api.responses import FastJSONResponse
from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.formats import TABLES, names, negotiate
from segb_server.backend.services.reports.folder import FOLDER
from segb_server.backend.services.reports.service import DEFAULT_LIMIT, MAX_LIMIT, describe, short_name
from segb_server.backend.services.sparql.catalog import Catalog, CatalogQuery

# Query-string names that page or format a report; every other name must be one of the report's parameters.
CONTROL_PARAMETERS = ("limit", "offset", "format", "after")
_OPENAPI_TYPES = {"iri": ("string", "uri"), "dateTime": ("string", "date-time"), "decimal": ("number", None)}


def _openapi_parameter(name: str, kind: str, description: str, default: str | None) -> dict[str, Any]:
    schema_type, schema_format = _OPENAPI_TYPES.get(kind, ("integer" if kind == "integer" else "string", None))
    schema: dict[str, Any] = {"type": schema_type}
    if schema_format:
        schema["format"] = schema_format
    if default is not None:
        schema["default"] = default
    return {"name": name, "in": "query", "required": False, "description": description, "schema": schema}


def _paging_parameters() -> list[dict[str, Any]]:
    return [
        {
            "name": "limit",
            "in": "query",
            "schema": {"type": "integer", "minimum": 1, "maximum": MAX_LIMIT, "default": DEFAULT_LIMIT},
            "description": f"Rows per page (1 to {MAX_LIMIT}).",
        },
        {
            "name": "offset",
            "in": "query",
            "schema": {"type": "integer", "minimum": 0, "maximum": MAX_OFFSET, "default": 0},
            "description": "Rows to skip.",
        },
        {
            "name": "after",
            "in": "query",
            "schema": {"type": "string"},
            "description": "The `next` cursor of the previous page: the next page, read from an index (keyset).",
        },
        {
            "name": "format",
            "in": "query",
            "schema": {"type": "string", "enum": names(TABLES)},
            "description": "json or csv; overrides Accept.",
        },
    ]


def _whole(request: Request, name: str, default: int, low: int, high: int) -> int:
    raw = request.query_params.get(name)
    if raw is None:
        return default
    try:
        value = int(raw)
    except ValueError:
        raise InvalidParameter(name, f"'{raw}' is not a whole number") from None
    if not low <= value <= high:
        raise InvalidParameter(name, f"must be between {low} and {high}")
    return value


async def answer_report(name: str, request: Request, services: ServicesDep) -> Response:
    limit = _whole(request, "limit", DEFAULT_LIMIT, 1, MAX_LIMIT)
    offset = _whole(request, "offset", 0, 0, MAX_OFFSET)
    fmt = negotiate(TABLES, request.headers.get("accept"), request.query_params.get("format"), what="a report")
    filters = {key: value for key, value in request.query_params.items() if key not in CONTROL_PARAMETERS}
    after = request.query_params.get("after")

    def work() -> Response:
        # Encoded in the worker thread too: a page of 10,000 rows would hold the event loop for milliseconds.
        table = services.reports.run(name, filters, limit, offset, after)
        if fmt.name == "csv":
            return Response(
                table.as_csv(),
                media_type=fmt.content_type,
                headers={"Content-Disposition": f'attachment; filename="{name}.csv"'},
            )
        return FastJSONResponse(table.as_json())

    return await run_in_threadpool(work)


def _report_endpoint(name: str) -> Callable[..., Awaitable[Response]]:
    async def endpoint(request: Request, services: ServicesDep, principal: Auditor) -> Response:
        return await answer_report(name, request, services)

    endpoint.__name__ = f"report_{name.replace('-', '_')}"
    return endpoint


def build_router(catalog: Catalog) -> APIRouter:
    """The listing, one route per report of `catalog` (documented from its header), and a 404 for others."""
    router = APIRouter(tags=["reports"])
    queries = catalog.under(FOLDER)

    @router.get("/reports", summary="List the audit reports")
    async def list_reports(services: ServicesDep, principal: Auditor) -> dict[str, list[dict[str, object]]]:
        return {"reports": [describe(query) for query in services.reports.reports()]}

    for query in queries:
        router.add_api_route(
            f"/reports/{short_name(query)}",
            _report_endpoint(short_name(query)),
            methods=["GET"],
            summary=query.title,
            description=_description(query),
            openapi_extra={"parameters": _parameters(query)},
            responses={200: {"content": {"application/json": {}, "text/csv": {}}}, 422: {}},
        )

    @router.get("/reports/{name}", include_in_schema=False)
    async def unknown_report(name: str, request: Request, services: ServicesDep, principal: Auditor) -> Response:
        return await answer_report(name, request, services)  # answers 404 naming the reports there are

    return router


def _parameters(query: CatalogQuery) -> list[dict[str, Any]]:
    filters = [_openapi_parameter(p.name, p.type, p.help, p.default) for p in query.parameters.values()]
    return filters + _paging_parameters()


def _description(query: CatalogQuery) -> str:
    return (
        f"{query.description}\n\nRows as `{{report, title, description, parameters, columns, rows, limit, offset, "
        "has_more, next, served_from, last_event_id, behind}}`, or CSV with `Accept: text/csv` or `?format=csv`. "
        "Filters are bound as typed values, never spliced into SPARQL; a bad or unknown filter is a 422 naming it. "
        "`last_event_id`: send it as `Last-Event-ID` to `GET /reports/stream` to hear of every change these rows "
        "do not include (null when the report is evaluated in full). `behind`: `{entries, seconds}` when the rows do "
        "not include everything robots have published yet (journal entries on their way, and how long the oldest has "
        "waited), else null."
    )
