"""GET /events: the whole events graph, streamed, in the RDF syntax the client asks for."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.services.formats import EXPORTS, names, negotiate
from segb_server.backend.services.graph.export import stream_graph, stream_received

router = APIRouter(tags=["export"])


@router.get(
    "/events",
    summary="Export the events graph",
    description=(
        "Streams every triple of the events graph. Turtle by default; `Accept: application/n-triples`, "
        "`application/n-quads` or `application/ld+json` (or `?format=ntriples|nquads|jsonld|turtle`) "
        "choose another syntax. 406 when none of the accepted types can be produced.\n\n"
        "`form=store` (default) is the graph as the store holds it: stores canonicalise literals "
        '(`"8.7e-01"^^xsd:double` becomes `"0.87"`, `xsd:long` becomes `xsd:integer`). `form=received` is the '
        "graph as robots sent it, read from the journal: every triple since the last clearing with its "
        "original lexical form and datatype (in N-Triples and N-Quads byte for byte as the journal keeps it)."
    ),
    responses={200: {"content": {fmt.media_type: {} for fmt in EXPORTS}}, 406: {}},
    response_class=StreamingResponse,
)
async def export_events(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    format: str | None = Query(None, description=f"{', '.join(names(EXPORTS))}; overrides Accept."),
    form: Literal["store", "received"] = Query("store", description="The store's view, or the journal's."),
) -> StreamingResponse:
    fmt = negotiate(EXPORTS, request.headers.get("accept"), format, what="the events graph")
    if form == "received":
        chunks = stream_received(services.writes.journal, fmt, services.store.graph_uri)
    else:
        # The store's first batch is read before answering, so a store that is down is a 503, not an answer
        # cut off midway.
        chunks = await run_in_threadpool(stream_graph, services.store, fmt)
    return StreamingResponse(chunks, media_type=fmt.content_type)
