"""/ledger: the ingest receipts, newest first, under the result of checking their hash chain."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import paging

router = APIRouter()

PAGE_ROWS = 100
MAX_ROWS = 1000  # the API's largest page


@router.get("/ledger", response_class=HTMLResponse)
async def ledger_page(request: Request) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    limit, offset = paging(request, PAGE_ROWS, MAX_ROWS)
    listing, verification = await asyncio.gather(
        client.get_json("/ledger", token=user_token, params={"limit": limit, "offset": offset}),
        client.get_json("/ledger/verify", token=user_token),
    )
    return render(
        request,
        "ledger.html",
        {
            "receipts": listing["receipts"],
            "total": listing["total"],
            "limit": limit,
            "offset": offset,
            "verification": verification,
        },
    )
