"""/logs/insert (admin): paste or upload a log (Turtle or N-Triples), check it with the API's
`POST /ttl/validate`, see what it would add, then publish it with `POST /ttl`; the result links to its
ledger receipt."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.api_client import BackendError
from segb_server.ui.csrf import check_csrf
from segb_server.ui.forms import read_upload_form
from segb_server.ui.log_preview import preview
from segb_server.ui.pages import ADMIN, backend, render, require, token, viewer

router = APIRouter()

MAX_INSERT_BYTES = 32 * 1024 * 1024  # the form as posted; larger logs go through `segb import` or the API


@router.get("/logs/insert", response_class=HTMLResponse)
async def insert_page(request: Request) -> HTMLResponse:
    require(request, ADMIN)
    return render(request, "insert.html", {"text": ""})


@router.post("/logs/insert", response_class=HTMLResponse)
async def insert_log(request: Request) -> HTMLResponse:
    form = await read_upload_form(request, MAX_INSERT_BYTES)
    check_csrf(request, form)
    # An uploaded file wins over the text box; either way the text comes back in the box for the next step.
    text = form.get("file") or form.get("text", "")
    if not text.strip():
        return render(request, "insert.html", {"text": text, "problem": "Paste a log or choose a file first."}, 400)
    client, user_token = backend(request), token(request)
    check = await client.post_json("/ttl/validate", {"ttl_content": text}, token=user_token)
    context: dict[str, Any] = {"text": text, "check": check}
    publishing = form.get("action") == "publish"
    if not check.get("valid"):
        # A check that finds errors did its job (200); a publish it stopped did not (422, nothing stored).
        return render(request, "insert.html", context, 422 if publishing else 200)
    if not publishing:
        context["preview"] = await preview(client, user_token, text)
        return render(request, "insert.html", context)
    try:
        context["published"] = await client.post_json(
            "/ttl", {"ttl_content": text, "user": viewer(request).username}, token=user_token
        )
    except BackendError as error:
        if error.status in (401, 403):
            raise
        context["problem"] = f"The API did not store the log: {error.detail}"
        return render(request, "insert.html", context, error.status)
    context["text"] = ""  # published: the box is ready for the next log
    return render(request, "insert.html", context)
