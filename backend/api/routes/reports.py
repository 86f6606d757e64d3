"""GET /reports and GET /reports/{name}: the audit reports as JSON or CSV."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, Response

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.paging import Offset
from segb_server.backend.services.catalog import CatalogQuery
from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.reports import short_name

router = APIRouter(tags=["reports"])

MAX_LIMIT = 10_000
# Query-string names that page or format a report; every other name is a report parameter.
_CONTROL_PARAMETERS = {"limit", "offset", "format"}


def describe(query: CatalogQuery) -> dict[str, object]:
    return {
        "name": short_name(query),
        "title": query.title,
        "description": query.description,
        "parameters": [
            {"name": p.name, "type": p.type, "default": p.default, "description": p.help}
            for p in query.parameters.values()
        ],
        "href": f"/reports/{short_name(query)}",
    }


@router.get("/reports", summary="List the audit reports")
async def list_reports(services: ServicesDep, principal: Auditor) -> dict[str, list[dict[str, object]]]:
    return {"reports": [describe(query) for query in services.reports.reports()]}


@router.get(
    "/reports/{name}",
    summary="Run one audit report",
    description=(
        "Rows of one report as `{report, title, columns, rows, limit, offset, has_more}`, or CSV with "
        "`Accept: text/csv` or `?format=csv`. Filters (`robot`, `human` IRIs; `since`, `until` ISO 8601 times "
        "with a zone; `threshold` where the report has it) are bound as typed values, never spliced into "
        "SPARQL. Unknown report → 404; a bad or unknown filter → 422 naming it."
    ),
    responses={200: {"content": {"application/json": {}, "text/csv": {}}}},
)
async def run_report(
    name: str,
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    robot: Annotated[str | None, Query(description="Robot IRI")] = None,
    human: Annotated[str | None, Query(description="Human IRI")] = None,
    since: Annotated[str | None, Query(description="ISO 8601 time with zone, inclusive")] = None,
    until: Annotated[str | None, Query(description="ISO 8601 time with zone, inclusive")] = None,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT)] = 1000,
    offset: Offset = 0,
    format: Annotated[str | None, Query(description="json or csv; overrides Accept")] = None,
) -> Response:
    if format not in (None, "json", "csv"):
        raise InvalidParameter("format", "must be json or csv")
    filters = {key: value for key, value in request.query_params.items() if key not in _CONTROL_PARAMETERS}
    table = await run_in_threadpool(services.reports.run, name, filters, limit, offset)
    wants_csv = format == "csv" or (format is None and "text/csv" in request.headers.get("accept", ""))
    if wants_csv:
        return Response(
            table.as_csv(),
            media_type="text/csv; charset=utf-8",
            headers={"Content-Disposition": f'attachment; filename="{name}.csv"'},
        )
    return JSONResponse(table.as_json())
