"""/findings: what the audit rules find, counted by rule and severity, then listed in time order; kept live."""

from __future__ import annotations

import asyncio
from typing import Any
from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response

from segb_server.ui.choices import participant_choices
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import query_values

router = APIRouter()

PAGE_FINDINGS = 100
FILTERS = ("robot", "human", "since", "until")
SEVERITIES = ("violation", "warning", "info")


def _filters(request: Request) -> dict[str, Any]:
    """The page's filters as the API takes them: one value each, `rule` and `severity` possibly several."""
    values: dict[str, Any] = dict(query_values(request, FILTERS))
    for name in ("rule", "severity"):
        chosen = [value for value in request.query_params.getlist(name) if value]
        if chosen:
            values[name] = chosen
    return values


@router.get("/findings", response_class=HTMLResponse)
async def findings_page(request: Request) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    filters = _filters(request)
    after = request.query_params.get("after") or None
    params = {**filters, "limit": PAGE_FINDINGS, **({"after": after} if after else {})}
    listing, page, choices = await asyncio.gather(
        client.get_json("/rules", token=user_token),
        client.get_json("/findings", token=user_token, params=params),
        participant_choices(request),
    )
    rules = {rule["id"]: rule for rule in listing["rules"]}
    return render(
        request,
        "findings.html",
        {
            "rules": rules,
            "page": page,
            "filters": filters,
            "choices": choices,
            "severities": SEVERITIES,
            "after": after,
            "names": {**choices["robots"], **choices["humans"]},
            "next_href": "?" + urlencode({**filters, "after": page["next"]}, doseq=True) if page["next"] else None,
        },
    )


@router.get("/findings/download.{fmt}")
async def download_findings(request: Request, fmt: str) -> Response:
    """The findings as a file, fetched with the viewer's token (the browser never talks to the API)."""
    if fmt not in ("csv", "json"):
        return Response("Downloads are .csv or .json", status_code=404, media_type="text/plain")
    params = {**_filters(request), "limit": 1000, "format": fmt}
    answer = await backend(request).request("GET", "/findings", token=token(request), params=params)
    return Response(
        answer.content,
        media_type=answer.headers.get("content-type", "application/octet-stream"),
        headers={"Content-Disposition": f'attachment; filename="findings.{fmt}"'},
    )
