"""/logs: the server's structured log (admin), filtered by lowest level and a text to contain, in pages."""

from __future__ import annotations

from typing import Any
from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import paging, query_values

router = APIRouter()

LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")
PAGE_ENTRIES = 50
MAX_PAGE_ENTRIES = 500
MAX_OFFSET = 2000  # the API reads back this many entries at most: a page past them is not linked
NEAR_PAGES = 2  # page links on each side of the current one (and the first and last)


@router.get("/logs", response_class=HTMLResponse)
async def logs_page(request: Request) -> HTMLResponse:
    filters = query_values(request, ("level", "contains"))
    limit, offset = paging(request, PAGE_ENTRIES, MAX_PAGE_ENTRIES)
    wanted = {"level": filters.get("level") or "INFO", "contains": filters.get("contains")}
    # The API refuses an offset past the entries it reads back with a message (422).
    params = {**wanted, "limit": limit, "offset": offset}
    answer = await backend(request).get_json("/logs/server", token=token(request), params=params)
    context = {
        "entries": answer["entries"],
        "total": answer["total"],
        "more": answer["more"],
        "source": answer["source"],
        "levels": LEVELS,
        "filters": {**wanted, "limit": limit},
        "offset": offset,
    }
    return render(request, "logs.html", {**context, **pages(wanted, limit, offset, answer["total"], answer["more"])})


def pages(wanted: dict[str, Any], limit: int, offset: int, total: int, more: bool) -> dict[str, Any]:
    """The pager: newer and older pages, and a link to each page (the first, the last and those near this one;
    None where pages are left out)."""

    def href(start: int) -> str:
        return "?" + urlencode({**{k: v for k, v in wanted.items() if v}, "limit": limit, "offset": start})

    reachable = total if not more else MAX_OFFSET + 1  # offsets below this have entries to show
    last = (min(reachable, MAX_OFFSET + 1) - 1) // limit if reachable else 0
    current = offset // limit
    near = {0, last, *range(max(0, current - NEAR_PAGES), min(last, current + NEAR_PAGES) + 1)}
    shown = sorted(near | {number + 1 for number in near if number + 2 in near})  # no "…" for one page left out
    links: list[dict[str, Any] | None] = []
    for before, number in zip([-1, *shown], shown, strict=False):
        if number > before + 1:
            links.append(None)
        links.append({"number": number + 1, "href": href(number * limit), "current": number * limit == offset})
    older = offset + limit
    return {
        "previous_href": href(max(0, offset - limit)) if offset else None,
        "next_href": href(older) if older < reachable and older <= MAX_OFFSET else None,
        "page_links": links if len(shown) > 1 else [],
    }
