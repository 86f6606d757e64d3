"""/timeline: one robot's or one human's events over a window, in time order (the investigator's view).

The page holds the window's first page of events; its script (static/timeline-live.js) fetches the rest page
by page from this UI (`/timeline/data`, which asks the API with the viewer's token) and follows the API's live
stream (relayed at `/live/timeline`). The viewer that draws them, `/timeline/viewer.js` and `.css`, is the
API's: the same one draws a timeline written as one HTML file.
"""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response
from markupsafe import Markup

from segb_server.ui.api_client import BackendError
from segb_server.ui.choices import participant_choices
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import query_values

router = APIRouter()

WINDOW = ("robot", "human", "since", "until")
FIRST_PAGE = 2000  # events in the page as it is sent; the rest follow in pages of PAGE (static/timeline-live.js)
DOWNLOADS = {"csv": "text/csv", "html": "text/html"}


def window(request: Request) -> dict[str, Any]:
    """The page's filters as the API takes them: the window, and the kinds (repeatable)."""
    values: dict[str, Any] = query_values(request, WINDOW)
    kinds = [kind for kind in request.query_params.getlist("kind") if kind]
    if kinds:
        values["kind"] = kinds
    return values


def data_block(rows: list[dict[str, Any]]) -> Markup:
    """Rows as a JSON data block for the page's script: no `<`, `>` or `&` left, so no text can end it."""
    text = json.dumps(rows, ensure_ascii=False, separators=(",", ":"))
    return Markup(text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026"))


@router.get("/timeline", response_class=HTMLResponse)
async def timeline_page(request: Request) -> HTMLResponse:
    filters = window(request)
    choices = await participant_choices(request)
    context: dict[str, Any] = {"filters": filters, "choices": choices, "query": request.url.query}
    if filters.get("robot") or filters.get("human"):
        params = {**filters, "limit": FIRST_PAGE}
        first = await backend(request).get_json("/timeline", token=token(request), params=params)
        context.update(page=first, rows=data_block(first["rows"]))
    return render(request, "timeline.html", context)


@router.get("/timeline/data")
async def timeline_data(request: Request) -> Response:
    """A page of the timeline, the API's JSON as it is (thousands of rows are not decoded and encoded again)."""
    params: dict[str, Any] = {**window(request)}
    for name in ("limit", "after"):
        if request.query_params.get(name):
            params[name] = request.query_params[name]
    answer = await backend(request).request("GET", "/timeline", token=token(request), params=params)
    return Response(answer.content, media_type="application/json")


@router.get("/timeline/download.{fmt}")
async def download(request: Request, fmt: str) -> Response:
    """The timeline as a file, fetched with the viewer's token: a page as CSV, or the window as one HTML file."""
    if fmt not in DOWNLOADS:
        raise BackendError(404, "Downloads are .csv or .html")
    params = {**window(request), "format": fmt, "limit": 10_000}
    answer = await backend(request).request("GET", "/timeline", token=token(request), params=params)
    return Response(
        answer.content,
        media_type=answer.headers.get("content-type", DOWNLOADS[fmt]),
        headers={"Content-Disposition": f'attachment; filename="timeline.{fmt}"'},
    )


@router.get("/timeline/viewer.{extension}")
async def viewer(request: Request, extension: str) -> Response:
    """The API's timeline viewer (script or style), served from this origin as the page's CSP requires."""
    answer = await backend(request).request("GET", f"/timeline/viewer.{extension}")
    return Response(
        answer.content,
        media_type=answer.headers.get("content-type", "text/plain"),
        headers={"Cache-Control": answer.headers.get("cache-control", "no-cache")},
    )
