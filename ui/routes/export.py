"""/export/graph.{ttl,nt,jsonld}: the whole events graph as a file, relayed chunk by chunk from the API's
`GET /events` with the viewer's token (the browser never talks to the API, and the graph is never held
whole in this process)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response, StreamingResponse
from starlette.background import BackgroundTask

from segb_server.ui.pages import backend, token

router = APIRouter()

# File suffix → (the API's `format`, the file's media type).
EXPORTS = {
    "ttl": ("turtle", "text/turtle; charset=utf-8"),
    "nt": ("ntriples", "application/n-triples"),
    "jsonld": ("jsonld", "application/ld+json"),
}


@router.get("/export/graph.{suffix}")
async def export_graph(request: Request, suffix: str) -> Response:
    if suffix not in EXPORTS:
        return Response("Downloads are graph.ttl, graph.nt or graph.jsonld", status_code=404, media_type="text/plain")
    fmt, media_type = EXPORTS[suffix]
    answer = await backend(request).open_stream("/events", token=token(request), params={"format": fmt})
    return StreamingResponse(
        answer.aiter_bytes(),
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="segb-graph.{suffix}"'},
        background=BackgroundTask(answer.aclose),
    )
