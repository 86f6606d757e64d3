"""/shared-context: the review queue, each ambiguous context beside its candidates, with accept/reject forms."""

from __future__ import annotations

import asyncio
import re
from collections.abc import Mapping
from typing import Any
from urllib.parse import quote

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from segb_server.ui.csrf import check_csrf
from segb_server.ui.display import short_iri, when
from segb_server.ui.forms import read_form
from segb_server.ui.namesakes import Name
from segb_server.ui.pages import backend, render, token
from segb_server.ui.participant_names import participant_names

router = APIRouter()

NOTICES = {
    "accepted": "Merged: the ambiguous context now resolves to the chosen one.",
    "rejected": "Rejected: the context stays apart, and these candidates will not be proposed for it again.",
    "reconciled": "Reconciled: every ambiguous context was examined again.",
}


@router.get("/shared-context", response_class=HTMLResponse)
async def review_page(request: Request, notice: str | None = None) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    queue, stats, names = await asyncio.gather(
        client.get_json("/shared-context/review/pending", token=user_token),
        client.get_json("/shared-context/stats", token=user_token),
        participant_names(request),
    )
    contexts = {context["uri"]: context for context in queue["contexts"]}
    in_review = {case["source_context_uri"] for case in queue["pending_cases"]}
    for context in contexts.values():
        context["summary"] = summary(context, names)
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


def event_words(kind: str) -> str:
    """`human_utterance` → `utterance`: the kind as words, without a leading `human` (the subject says who)."""
    words = re.sub(r"[\s_\-]+", " ", kind).strip()
    return words.removeprefix("human ") or "event"


def summary(context: Mapping[str, Any], names: Mapping[str, Name]) -> str:
    """A shared event has no name: `Maria's utterance (heard by ARI) at 10:00:11 — “Hi!”`, its text as a robot
    logged it (the context's own text is lowercased for matching)."""
    subject_uri = str(context.get("subject_uri") or "")
    subject = names.get(subject_uri) or Name(short_iri(subject_uri))
    kind = event_words(str(context.get("event_kind") or ""))
    said = f"{subject.label}'s {kind}" if subject_uri else f"An unattributed {kind}"
    robots = [_name(observation.get("robot_uri"), names) for observation in context["observations"]]
    robots = [robot for robot in dict.fromkeys(robots) if robot]
    sensed = "heard" if context.get("modality") == "speech" else "observed"
    if robots:
        said += f" ({sensed} by {', '.join(robots)})"
    elif subject.qualifier:  # no robot said it heard them: which Maria, then
        said += f" ({subject.label} met by {subject.qualifier})"
    said += f" at {when(context.get('observed_at'), with_date=False)}"
    text = next((o["text"] for o in context["observations"] if o.get("text")), None) or context.get("canonical_text")
    return f"{said} — “{text}”" if text else said


def _name(iri: object, names: Mapping[str, Name]) -> str:
    """A robot's name; its IRI's last part when the graph does not know it (yet)."""
    known = names.get(str(iri or ""))
    return str(known) if known else short_iri(iri)


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
