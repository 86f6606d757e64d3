"""/logs: the server's structured log (admin), filtered by lowest level, a text to contain, and how many."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import query_values

router = APIRouter()

LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")
DEFAULT_LIMIT = 200


@router.get("/logs", response_class=HTMLResponse)
async def logs_page(request: Request) -> HTMLResponse:
    filters = query_values(request, ("level", "contains", "limit"))
    params = {"level": filters.get("level") or "INFO", "contains": filters.get("contains"), "limit": DEFAULT_LIMIT}
    if filters.get("limit"):
        params["limit"] = filters["limit"]  # the API refuses a bad value with a message (422)
    answer = await backend(request).get_json("/logs/server", token=token(request), params=params)
    return render(
        request,
        "logs.html",
        {"entries": answer["entries"], "source": answer["source"], "levels": LEVELS, "filters": params},
    )
