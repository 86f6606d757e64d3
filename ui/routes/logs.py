"""/logs: the server's structured log (admin), filtered by lowest level and a text to contain, in pages."""

from __future__ import annotations

from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import paging, query_values

router = APIRouter()

LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")
PAGE_ENTRIES = 50
MAX_PAGE_ENTRIES = 500


@router.get("/logs", response_class=HTMLResponse)
async def logs_page(request: Request) -> HTMLResponse:
    filters = query_values(request, ("level", "contains"))
    limit, offset = paging(request, PAGE_ENTRIES, MAX_PAGE_ENTRIES)
    wanted = {"level": filters.get("level") or "INFO", "contains": filters.get("contains")}
    # One entry more than the page shows tells whether a next page exists. The API refuses an offset past the
    # entries it reads back (2000) with a message (422).
    params = {**wanted, "limit": limit + 1, "offset": offset}
    answer = await backend(request).get_json("/logs/server", token=token(request), params=params)
    entries = answer["entries"]

    def page_href(start: int) -> str:
        return "?" + urlencode({**{k: v for k, v in wanted.items() if v}, "limit": limit, "offset": start})

    return render(
        request,
        "logs.html",
        {
            "entries": entries[:limit],
            "source": answer["source"],
            "levels": LEVELS,
            "filters": {**wanted, "limit": limit},
            "offset": offset,
            "previous_href": page_href(max(0, offset - limit)) if offset else None,
            "next_href": page_href(offset + limit) if len(entries) > limit else None,
        },
    )
