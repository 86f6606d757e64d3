"""/reports: every audit report on one page, each on its own page, and their CSV/JSON downloads."""

from __future__ import annotations

import asyncio
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response

from segb_server.ui.api_client import BackendError
from segb_server.ui.choices import participant_choices
from segb_server.ui.findings_marks import findings_about
from segb_server.ui.namesakes import Name, entity_names
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import paging, query_values
from segb_server.ui.report_views import OVERVIEW_ORDER, view_of

router = APIRouter()

OVERVIEW_ROWS = 200  # fetched per report: charts and conversations draw them all
OVERVIEW_TABLE_ITEMS = 10  # listed per table on the overview; each report's own page lists every row it has
PAGE_ROWS = 500
_catalog: dict[str, dict[str, Any]] = {}


async def report_catalog(request: Request) -> dict[str, dict[str, Any]]:
    """Every report the API serves, with its parameters (GET /reports), asked once: the API loads its catalog
    at start-up, so it does not change while it runs."""
    if not _catalog:
        listing = await backend(request).get_json("/reports", token=token(request))
        _catalog.update({report["name"]: report for report in listing["reports"]})
    return _catalog


def parameters_of(reports: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The parameters of the reports, each name once, in the order the reports declare them."""
    found: dict[str, dict[str, Any]] = {}
    for report in reports:
        for parameter in report["parameters"]:
            found.setdefault(parameter["name"], parameter)
    return list(found.values())


def report_filters(request: Request, parameters: list[dict[str, Any]]) -> dict[str, str]:
    """The page's values for these parameters (times the browser picked get their UTC zone)."""
    times = tuple(p["name"] for p in parameters if p["type"] == "dateTime")
    return query_values(request, tuple(p["name"] for p in parameters), times)


def _section(name: str, table: dict[str, Any], described: dict[str, Any], names: dict[str, Name]) -> dict[str, Any]:
    return {"name": name, "info": described, "table": table, **view_of(name, table, names)}


async def _mark_findings(request: Request, sections: list[dict[str, Any]]) -> None:
    """The conversations mark each message a finding is about (or whose activity one is about)."""
    for section in sections:
        if section["name"] == "conversations":
            rows = section["table"]["rows"]
            section["marks"] = await findings_about(
                request, [row.get(key) for row in rows for key in ("message", "activity")]
            )


def live_after(tables: list[dict[str, Any]]) -> str:
    """Where the page's live stream starts: the oldest change the page's rows are known to include, so a change
    made while the page travels to the browser is still announced (empty: from when the stream opens)."""
    seen = [table["last_event_id"] for table in tables if table.get("last_event_id") is not None]
    return str(min(seen)) if seen else ""


def behind(tables: list[dict[str, Any]]) -> str | None:
    """What the page says when its rows do not include everything robots have published yet (the server is
    catching up): how far behind, in time and in posts."""
    lags = [table["behind"] for table in tables if table.get("behind")]
    if not lags:
        return None
    worst = max(lags, key=lambda lag: (lag["seconds"], lag["entries"]))
    posts = worst["entries"]
    return (
        f"These rows are {worst['seconds']:.1f} s behind what robots have published ({posts} "
        f"{'post' if posts == 1 else 'posts'} on the way): the server is catching up."
    )


def _supported(filters: dict[str, str], described: dict[str, Any]) -> dict[str, str]:
    accepted = {parameter["name"] for parameter in described["parameters"]}
    return {name: value for name, value in filters.items() if name in accepted}


@router.get("/reports", response_class=HTMLResponse)
async def reports_overview(request: Request) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    described = await report_catalog(request)
    names = [name for name in OVERVIEW_ORDER if name in described] + sorted(set(described) - set(OVERVIEW_ORDER))
    parameters = parameters_of([described[name] for name in names])
    filters = report_filters(request, parameters)

    async def fetch(name: str) -> dict[str, Any]:
        params = {**_supported(filters, described[name]), "limit": OVERVIEW_ROWS}
        return await client.get_json(f"/reports/{name}", token=user_token, params=params)

    choices, *tables = await asyncio.gather(participant_choices(request), *(fetch(name) for name in names))
    # One name per entity on the whole page: a namesake carries the same qualifier in every report.
    shown = entity_names((table["rows"] for table in tables), choices["met"])
    sections = [_section(name, table, described[name], shown) for name, table in zip(names, tables, strict=True)]
    await _mark_findings(request, sections)
    return render(
        request,
        "reports.html",
        {
            "sections": sections,
            "preview": OVERVIEW_TABLE_ITEMS,
            "parameters": parameters,
            "filters": filters,
            "choices": choices,
            "query": request.url.query,
            "live_after": live_after(tables),
            "behind": behind(tables),
        },
    )


@router.get("/reports/{name}", response_class=HTMLResponse)
async def one_report(request: Request, name: str) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    described = (await report_catalog(request)).get(name)
    if described is None:
        raise BackendError(404, f"No report named '{name}'.")
    filters = report_filters(request, described["parameters"])
    limit, offset = paging(request, PAGE_ROWS, described["max_limit"])
    table, choices = await asyncio.gather(
        client.get_json(f"/reports/{name}", token=user_token, params={**filters, "limit": limit, "offset": offset}),
        participant_choices(request),
    )
    section = _section(name, table, described, entity_names([table["rows"]], choices["met"]))
    await _mark_findings(request, [section])
    return render(
        request,
        "report.html",
        {
            "report": section,
            "parameters": described["parameters"],
            "filters": filters,
            "choices": choices,
            "query": request.url.query,
            "limit": limit,
            "offset": offset,
            "live_after": live_after([table]),
            "behind": behind([table]),
        },
    )


@router.get("/reports/{name}/download.{fmt}")
async def download_report(request: Request, name: str, fmt: str) -> Response:
    """The report as a file, fetched with the viewer's token (the browser never talks to the API)."""
    if fmt not in ("csv", "json"):
        return Response("Downloads are .csv or .json", status_code=404, media_type="text/plain")
    described = (await report_catalog(request)).get(name)
    if described is None:
        raise BackendError(404, f"No report named '{name}'.")
    limit, offset = paging(request, described["max_limit"], described["max_limit"])
    filters = report_filters(request, described["parameters"])
    params = {**filters, "limit": limit, "offset": offset, "format": fmt}
    response = await backend(request).request("GET", f"/reports/{name}", token=token(request), params=params)
    return Response(
        response.content,
        media_type=response.headers.get("content-type", "application/octet-stream"),
        headers={"Content-Disposition": f'attachment; filename="{name}.{fmt}"'},
    )
