"""/shared-context: the review queue, each ambiguous context beside its candidates, with accept/reject forms."""

from __future__ import annotations

import asyncio
from urllib.parse import quote

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from segb_server.ui.csrf import check_csrf
from segb_server.ui.display import short_iri
from segb_server.ui.forms import read_form
from segb_server.ui.namesakes import tell_apart
from segb_server.ui.pages import backend, render, token

router = APIRouter()

NOTICES = {
    "accepted": "Merged: the ambiguous context now resolves to the chosen one.",
    "rejected": "Rejected: the context stays apart, and these candidates will not be proposed for it again.",
    "reconciled": "Reconciled: every ambiguous context was examined again.",
}


@router.get("/shared-context", response_class=HTMLResponse)
async def review_page(request: Request, notice: str | None = None) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    queue, stats = await asyncio.gather(
        client.get_json("/shared-context/review/pending", token=user_token),
        client.get_json("/shared-context/stats", token=user_token),
    )
    contexts = {context["uri"]: context for context in queue["contexts"]}
    in_review = {case["source_context_uri"] for case in queue["pending_cases"]}
    # Subjects and robots are shown by IRI tail: two robots' `human_maria` must not look like one person.
    shown = {context.get("subject_uri") for context in contexts.values()} | {
        observation.get("robot_uri") for context in contexts.values() for observation in context["observations"]
    }
    names = tell_apart({iri: short_iri(iri) for iri in shown if iri})
    return render(
        request,
        "shared-context.html",
        {
            "notice": NOTICES.get(notice or ""),
            "stats": stats,
            "cases": queue["pending_cases"],
            "contexts": contexts,
            "names": names,
            "waiting": [context for context in queue["unresolved_contexts"] if context["uri"] not in in_review],
        },
    )


@router.post("/shared-context/review/{case_id}/accept")
async def accept(request: Request, case_id: str) -> Response:
    form = await read_form(request)
    check_csrf(request, form)
    return await _decide(request, case_id, "accept", {"target_context_uri": form.get("target_context_uri", "")})


@router.post("/shared-context/review/{case_id}/reject")
async def reject(request: Request, case_id: str) -> Response:
    check_csrf(request, await read_form(request))
    return await _decide(request, case_id, "reject", {})


async def _decide(request: Request, case_id: str, decision: str, body: dict[str, str]) -> Response:
    path = f"/shared-context/review/{quote(case_id, safe='')}/{decision}"
    await backend(request).post_json(path, body, token=token(request))
    return RedirectResponse(f"/shared-context?notice={decision}ed", status_code=303)


@router.post("/shared-context/reconcile")
async def reconcile(request: Request) -> Response:
    check_csrf(request, await read_form(request))
    await backend(request).post_json("/shared-context/reconcile", {}, token=token(request))
    return RedirectResponse("/shared-context?notice=reconciled", status_code=303)
