"""GET /events: the whole events graph, streamed, in the RDF syntax the client asks for."""

from __future__ import annotations

from itertools import chain

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.export import EXPORT_FORMATS, FORMAT_NAMES, negotiate, stream_graph

router = APIRouter(tags=["export"])


@router.get(
    "/events",
    summary="Export the events graph",
    description=(
        "Streams every triple of the events graph. Turtle by default; `Accept: application/n-triples`, "
        "`application/n-quads` or `application/ld+json` (or `?format=ntriples|nquads|jsonld|turtle`) "
        "choose another syntax. 406 when none of the accepted types can be produced."
    ),
    responses={200: {"content": {media: {} for media in EXPORT_FORMATS}}, 406: {}},
    response_class=StreamingResponse,
)
async def export_events(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    format: str | None = Query(None, description="turtle, ntriples, nquads or jsonld; overrides Accept."),
) -> StreamingResponse:
    if format is not None and format not in FORMAT_NAMES:
        raise InvalidParameter("format", f"must be one of {', '.join(FORMAT_NAMES)}")
    fmt = EXPORT_FORMATS[FORMAT_NAMES[format]] if format else negotiate(request.headers.get("accept"))
    chunks = stream_graph(services.store, fmt)
    # Pull the first chunk here so a store that is down is a 503, not a response cut off midway.
    first = await run_in_threadpool(next, chunks, b"")
    return StreamingResponse(chain([first], chunks), media_type=f"{fmt.media_type}; charset=utf-8")
