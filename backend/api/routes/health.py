"""Liveness and readiness probes, public, cheap, and never queued behind ingest work."""

from __future__ import annotations

import json

import anyio
from fastapi import APIRouter
from fastapi.responses import JSONResponse

from segb_server.backend.api.deps import ServicesDep
from segb_server.backend.store.base import StoreError

router = APIRouter(tags=["health"])

# A limiter of its own: readiness pings never wait for threads busy with large ingests.
_probe_threads = anyio.CapacityLimiter(4)


class ProbeResponse(JSONResponse):
    """Spaced JSON, so `curl -s .../healthz/ready` prints `{"ready": true, "virtuoso": true}` verbatim."""

    def render(self, content: object) -> bytes:
        return json.dumps(content).encode("utf-8")


@router.get(
    "/healthz/live",
    summary="Liveness",
    description='Always `{"live": true}` while the process serves HTTP.',
    response_class=ProbeResponse,
    responses={200: {"content": {"application/json": {"example": {"live": True}}}}},
)
async def live() -> ProbeResponse:
    return ProbeResponse({"live": True})


@router.get(
    "/healthz/ready",
    summary="Readiness",
    description=(
        'Pings the triple store. 200 with `{"ready": true, "<store kind>": true}` when it answers, '
        '503 with `"ready": false` (and a `detail`) when it does not. The store kind is `virtuoso`, '
        "`oxigraph`, `memory` or `sparql`, so on the Virtuoso stack the body is "
        '`{"ready": true, "virtuoso": true}`.'
    ),
    response_class=ProbeResponse,
    responses={
        200: {"content": {"application/json": {"example": {"ready": True, "virtuoso": True}}}},
        503: {"content": {"application/json": {"example": {"ready": False, "virtuoso": False, "detail": "…"}}}},
    },
)
async def ready(services: ServicesDep) -> ProbeResponse:
    store = services.store
    try:
        await anyio.to_thread.run_sync(store.ping, limiter=_probe_threads)
    except StoreError as error:
        return ProbeResponse({"ready": False, store.kind: False, "detail": str(error)}, status_code=503)
    return ProbeResponse({"ready": True, store.kind: True})
