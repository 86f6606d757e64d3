"""Liveness and readiness probes, public, cheap, and never queued behind ingest work."""

from __future__ import annotations

import json

import anyio
from fastapi import APIRouter
from fastapi.responses import JSONResponse

from segb_server.backend.api.deps import ServicesDep
from segb_server.backend.state.database import StateUnavailable
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
        'Pings the triple store and checks the journal. 200 with `{"ready": true, "<store kind>": true}` when the '
        'store answers, 503 with `"ready": false` (and a `detail`) when it does not or when the journal\'s disk '
        'is full (`"journal": false`). The store kind is `virtuoso`, `oxigraph`, `memory` or `sparql`, so on '
        'the Virtuoso stack the body is `{"ready": true, "virtuoso": true}`. While the store has journal entries '
        'to apply, `"apply_lag": {"entries", "seconds"}` says how far behind it is, and '
        '`"reports_lag": {"entries", "seconds"}` how far the views (the reports\' rows, the timeline, the '
        "findings, the graph index) are behind the store, the one furthest behind; each view advances at its own "
        'pace, and `"views_lag": {view: {"entries", "seconds"}}` tells each one behind (all absent once caught up); '
        '`"views_building"` lists the views being built (at '
        "start, or after a change of their definitions), absent once built; while the views are behind because "
        'reading the store or writing their own storage fails, `"views_error"` tells the error being retried.'
    ),
    response_class=ProbeResponse,
    responses={
        200: {"content": {"application/json": {"example": {"ready": True, "virtuoso": True}}}},
        503: {"content": {"application/json": {"example": {"ready": False, "virtuoso": False, "detail": "…"}}}},
    },
)
async def ready(services: ServicesDep) -> ProbeResponse:
    store = services.store

    def probe() -> tuple[dict[str, object], int]:
        body: dict[str, object] = {"ready": True, store.kind: True}
        status = 200
        try:
            store.ping()
        except StoreError as error:
            body.update({"ready": False, store.kind: False, "detail": str(error)})
            status = 503
        try:
            services.writes.journal.ping()
        except StateUnavailable as error:
            body.update({"ready": False, "journal": False, "detail": f"journal: {error}"})
            return body, 503
        if not services.writes.journal.storage_ok():
            body.update(
                {"ready": False, "journal": False, "detail": f"journal: {services.writes.journal.storage_problem}"}
            )
            status = 503
        lag = services.writes.lag()
        if (
            lag.apply_entries
        ):  # only then: the tutorial's `{"ready": true, "virtuoso": true}` stays exact when caught up
            body["apply_lag"] = {"entries": lag.apply_entries, "seconds": round(lag.apply_seconds, 3)}
        if lag.views_entries:  # the views' oldest: the reports' rows, the timeline, the findings, the graph index
            body["reports_lag"] = {"entries": lag.views_entries, "seconds": round(lag.views_seconds, 3)}
            # Each view advances at its own pace: which ones are behind, and how far.
            body["views_lag"] = {
                view: {"entries": entries, "seconds": round(seconds, 3)}
                for view, (entries, seconds) in sorted(services.writes.view_lags().items())
            }
        building = services.writes.building_views()
        if building:
            body["views_building"] = building
        if (lag.views_entries or building) and (views_error := services.writes.views_error()):
            body["views_error"] = views_error  # why they stay behind: an operator's first question
        return body, status

    body, status = await anyio.to_thread.run_sync(probe, limiter=_probe_threads)
    return ProbeResponse(body, status_code=status)
