"""Health page: runs both probes when opened, so the state is on screen without a click."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.api_client import BackendUnavailable
from segb_server.ui.pages import backend, render

router = APIRouter()


@router.get("/health", response_class=HTMLResponse)
async def health_page(request: Request) -> HTMLResponse:
    client = backend(request)
    try:
        (live_status, live), (ready_status, ready) = await asyncio.gather(
            client.probe("/healthz/live"), client.probe("/healthz/ready")
        )
    except BackendUnavailable as error:
        return render(request, "health.html", {"unavailable": str(error), "backend_url": client.base_url})
    store_kind = next((key for key in (ready or {}) if key not in ("ready", "detail")), "store")
    return render(
        request,
        "health.html",
        {
            "backend_url": client.base_url,
            "live": live_status == 200 and bool((live or {}).get("live")),
            "ready": ready_status == 200 and bool((ready or {}).get("ready")),
            "store_kind": store_kind,
            "detail": (ready or {}).get("detail"),
        },
    )
