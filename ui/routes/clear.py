"""/logs/delete (admin): clear the events graph with `POST /ttl/delete_all`, after typing DELETE to confirm.
The result says how many triples went and links to the clearing's ledger receipt."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from segb_server.ui.csrf import check_csrf
from segb_server.ui.forms import read_form
from segb_server.ui.pages import ADMIN, backend, render, require, token

router = APIRouter()

CONFIRMATION = "DELETE"
COUNT = "SELECT (COUNT(*) AS ?triples) WHERE { ?s ?p ?o }"


async def _stored(request: Request) -> int | None:
    answer = (await backend(request).sparql(COUNT, "json", token=token(request))).json()
    bindings = answer["results"]["bindings"]
    return int(bindings[0]["triples"]["value"]) if bindings else None


@router.get("/logs/delete", response_class=HTMLResponse)
async def clear_page(request: Request) -> HTMLResponse:
    require(request, ADMIN)
    return render(request, "clear.html", {"stored": await _stored(request), "confirmation": CONFIRMATION})


@router.post("/logs/delete", response_class=HTMLResponse)
async def clear_graph(request: Request) -> HTMLResponse:
    form = await read_form(request)
    check_csrf(request, form)
    context = {"confirmation": CONFIRMATION}
    if form.get("confirm", "").strip() != CONFIRMATION:
        problem = f"Type {CONFIRMATION} (in capitals) to confirm. Nothing was removed."
        return render(request, "clear.html", {**context, "problem": problem, "stored": await _stored(request)}, 400)
    cleared = await backend(request).post_json("/ttl/delete_all", {}, token=token(request))
    return render(request, "clear.html", {**context, "cleared": cleared, "stored": await _stored(request)})
