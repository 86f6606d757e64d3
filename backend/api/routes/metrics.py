"""GET /metrics: the server's metrics in the Prometheus text format, for an auditor's token or the scraper's own
METRICS_TOKEN."""

from __future__ import annotations

import hmac

import anyio
from fastapi import APIRouter, Depends, Request
from fastapi.responses import Response

from segb_server.backend.api.deps import ServicesDep, SettingsDep, get_principal
from segb_server.backend.auth import authorize
from segb_server.backend.services.observability.metrics import CONTENT_TYPE, exposition
from segb_server.backend.services.observability.readings import Readings

router = APIRouter(tags=["health"])


async def scraper(request: Request, settings: SettingsDep) -> None:
    """Let in the bearer of METRICS_TOKEN (a Prometheus job's `authorization: credentials`), else an auditor."""
    given = request.headers.get("authorization", "")
    if settings.metrics_token and hmac.compare_digest(given.encode(), f"Bearer {settings.metrics_token}".encode()):
        return
    authorize(await get_principal(request, settings), ("auditor",))


@router.get(
    "/metrics",
    summary="Prometheus metrics",
    description=(
        "The Prometheus text format: posts and triples accepted and refused (by reason), ingest latency, the "
        "journal's and the views' lag, findings by rule and severity, the store's health, erasures, evidence "
        "bundles served, webhook deliveries and traces dropped. Summed over every API worker. Needs the auditor "
        "role, or `Authorization: Bearer <METRICS_TOKEN>`."
    ),
    dependencies=[Depends(scraper)],
    responses={200: {"content": {CONTENT_TYPE: {}}}},
)
async def metrics(services: ServicesDep) -> Response:
    text = await anyio.to_thread.run_sync(exposition, [Readings(services)])  # pings the store, reads the views
    return Response(text, media_type=CONTENT_TYPE)
