"""/reports: every audit report on one page, each on its own page, and their CSV/JSON downloads."""

from __future__ import annotations

import asyncio
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response

from segb_server.ui.choices import participant_choices
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import query_values
from segb_server.ui.report_views import OVERVIEW_ORDER, view_of

router = APIRouter()

FILTER_NAMES = ("robot", "human", "since", "until", "threshold")
OVERVIEW_ROWS = 200
PAGE_ROWS = 500


def report_filters(request: Request) -> dict[str, str]:
    return query_values(request, FILTER_NAMES)


def _paging(request: Request, default_limit: int) -> tuple[int, int]:
    def whole(name: str, default: int) -> int:
        raw = request.query_params.get(name, "")
        return int(raw) if raw.isdigit() else default

    return max(1, min(whole("limit", default_limit), 10_000)), whole("offset", 0)


def _section(name: str, table: dict[str, Any], described: dict[str, Any]) -> dict[str, Any]:
    return {"name": name, "info": described, "table": table, **view_of(name, table)}


def _supported(filters: dict[str, str], described: dict[str, Any]) -> dict[str, str]:
    accepted = {parameter["name"] for parameter in described["parameters"]}
    return {name: value for name, value in filters.items() if name in accepted}


@router.get("/reports", response_class=HTMLResponse)
async def reports_overview(request: Request) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    listing = (await client.get_json("/reports", token=user_token))["reports"]
    described = {report["name"]: report for report in listing}
    names = [name for name in OVERVIEW_ORDER if name in described] + sorted(set(described) - set(OVERVIEW_ORDER))
    filters = report_filters(request)

    async def fetch(name: str) -> dict[str, Any]:
        params = {**_supported(filters, described[name]), "limit": OVERVIEW_ROWS}
        return await client.get_json(f"/reports/{name}", token=user_token, params=params)

    choices, *tables = await asyncio.gather(participant_choices(request), *(fetch(name) for name in names))
    sections = [_section(name, table, described[name]) for name, table in zip(names, tables, strict=True)]
    return render(
        request,
        "reports.html",
        {"sections": sections, "filters": filters, "choices": choices, "query": request.url.query},
    )


@router.get("/reports/{name}", response_class=HTMLResponse)
async def one_report(request: Request, name: str) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    filters = report_filters(request)
    limit, offset = _paging(request, PAGE_ROWS)
    table, choices, listing = await asyncio.gather(
        client.get_json(f"/reports/{name}", token=user_token, params={**filters, "limit": limit, "offset": offset}),
        participant_choices(request),
        client.get_json("/reports", token=user_token),
    )
    described = next(report for report in listing["reports"] if report["name"] == name)
    return render(
        request,
        "report.html",
        {
            "report": _section(name, table, described),
            "filters": filters,
            "choices": choices,
            "query": request.url.query,
            "limit": limit,
            "offset": offset,
        },
    )


@router.get("/reports/{name}/download.{fmt}")
async def download_report(request: Request, name: str, fmt: str) -> Response:
    """The report as a file, fetched with the viewer's token (the browser never talks to the API)."""
    if fmt not in ("csv", "json"):
        return Response("Downloads are .csv or .json", status_code=404, media_type="text/plain")
    limit, offset = _paging(request, 10_000)
    params = {**report_filters(request), "limit": limit, "offset": offset, "format": fmt}
    response = await backend(request).request("GET", f"/reports/{name}", token=token(request), params=params)
    return Response(
        response.content,
        media_type=response.headers.get("content-type", "application/octet-stream"),
        headers={"Content-Disposition": f'attachment; filename="{name}.{fmt}"'},
    )
