"""/live/reports, /live/findings and /live/graph: the API's streams of view changes (Server-Sent Events), relayed
with the viewer's session, so the page's script connects to its own origin (the CSP allows nothing else) and no
token is ever in a URL."""

from __future__ import annotations

import httpx
from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse
from starlette.background import BackgroundTask

from segb_server.ui.pages import backend, token

router = APIRouter()

# The stream stays open: no read timeout (the API sends a comment every 15 s), a bounded connect.
STREAM_TIMEOUT = httpx.Timeout(10.0, read=None)


@router.get("/live/reports")
async def live_reports(request: Request) -> StreamingResponse:
    return await _relay(request, "/reports/stream", {"report": request.query_params.getlist("report")})


@router.get("/live/findings")
async def live_findings(request: Request) -> StreamingResponse:
    return await _relay(request, "/findings/stream", {})


@router.get("/live/graph")
async def live_graph(request: Request) -> StreamingResponse:
    return await _relay(request, "/graph/stream", {})


async def _relay(request: Request, path: str, params: dict[str, list[str]]) -> StreamingResponse:
    # A reconnecting EventSource sends Last-Event-ID; a page resuming after a pause passes `after=` instead.
    # Event ids are digits: anything else was never sent by a stream, and goes no further (the stream starts
    # from now) rather than into a header of the request to the API.
    resume = request.headers.get("last-event-id") or request.query_params.get("after") or ""
    if not (resume.isascii() and resume.replace(".", "", 1).isdigit()):  # the findings' ids are `rows.shapes`
        resume = ""
    answer = await backend(request).open_stream(
        path,
        token=token(request),
        params=params,
        headers={"Last-Event-ID": resume} if resume else None,
        timeout=STREAM_TIMEOUT,
    )
    return StreamingResponse(
        answer.aiter_raw(),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
        background=BackgroundTask(answer.aclose),
    )
