"""/people (admin): the people the log holds, each with a link to everything held about them (GET
/humans/{iri}/export, relayed), and erasing one (POST /humans/erase): first a preview of what would go (the same
call with `dry_run`, which writes nothing), then the erasure itself after typing ERASE to confirm."""

from __future__ import annotations

from urllib.parse import quote

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response

from segb_server.ui import vocabulary
from segb_server.ui.api_client import BackendError
from segb_server.ui.csrf import check_csrf
from segb_server.ui.forms import read_form
from segb_server.ui.pages import ADMIN, backend, render, require, token

router = APIRouter()

CONFIRMATION = "ERASE"


def people_query(known: vocabulary.Vocabulary) -> str:
    """Every human the log holds with their display name, by the server's rules of reading (GET /vocabulary: the
    classes that make a human, the name predicates best first)."""
    classes = " ".join(f"<{iri}>" for iri in known.human_classes)
    names = [f"?name{index}" for index in range(len(known.name_predicates))]
    optionals = " ".join(
        f"OPTIONAL {{ ?human <{predicate}> {name} }}"
        for predicate, name in zip(known.name_predicates, names, strict=True)
    )
    named = f"BIND (COALESCE({', '.join(names)}) AS ?named)" if names else ""
    return (
        f"SELECT ?human (SAMPLE(?named) AS ?name) WHERE {{ ?human a ?class . VALUES ?class {{ {classes} }} "
        f"{optionals} {named} }} GROUP BY ?human ORDER BY ?name ?human LIMIT 1000"
    )


EXPORT_FORMATS = {"html": "text/html; charset=utf-8", "turtle": "text/turtle; charset=utf-8"}
SUFFIX = {"html": "html", "turtle": "ttl"}


async def _people(request: Request) -> list[dict[str, str]]:
    known = await vocabulary.ensure(backend(request))
    answer = (await backend(request).sparql(people_query(known), "json", token=token(request))).json()
    return [
        {"iri": row["human"]["value"], "name": row.get("name", {}).get("value", "")}
        for row in answer["results"]["bindings"]
    ]


@router.get("/people", response_class=HTMLResponse)
async def people_page(request: Request) -> HTMLResponse:
    require(request, ADMIN)
    return render(request, "people.html", {"people": await _people(request), "confirmation": CONFIRMATION})


@router.post("/people/preview", response_class=HTMLResponse)
async def preview(request: Request) -> HTMLResponse:
    """What erasing a person would take, counted by kind, above the erase form filled in for them."""
    form = await read_form(request)
    check_csrf(request, form)
    iri = form.get("iri", "").strip()
    context = {"confirmation": CONFIRMATION, "iri": iri, "reason": form.get("reason", "")}
    try:
        answer = await backend(request).post_json("/humans/erase", {"iri": iri, "dry_run": True}, token=token(request))
    except BackendError as error:
        if error.status in (401, 403):
            raise
        problem = f"Nothing can be erased for this IRI: {error.detail}"
        people = await _people(request)
        return render(request, "people.html", {**context, "problem": problem, "people": people}, error.status)
    return render(request, "people.html", {**context, "preview": answer, "people": await _people(request)})


@router.post("/people/erase", response_class=HTMLResponse)
async def erase(request: Request) -> HTMLResponse:
    form = await read_form(request)
    check_csrf(request, form)
    context = {"confirmation": CONFIRMATION, "iri": form.get("iri", ""), "reason": form.get("reason", "")}
    if form.get("confirm", "").strip() != CONFIRMATION:
        problem = f"Type {CONFIRMATION} (in capitals) to confirm. Nothing was erased."
        return render(request, "people.html", {**context, "problem": problem, "people": await _people(request)}, 400)
    body = {"iri": form.get("iri", "").strip(), "reason": form.get("reason", "")}
    erased = await backend(request).post_json("/humans/erase", body, token=token(request))
    return render(
        request, "people.html", {"confirmation": CONFIRMATION, "erased": erased, "people": await _people(request)}
    )


@router.get("/people/export")
async def export(request: Request, iri: str, format: str = "html") -> Response:
    require(request, ADMIN)
    if format not in EXPORT_FORMATS:
        return Response("format is html or turtle", status_code=422, media_type="text/plain")
    answer = await backend(request).request(
        "GET", f"/humans/{quote(iri, safe='')}/export", token=token(request), params={"format": format}
    )
    disposition = "inline" if format == "html" else "attachment"
    headers = {"Content-Disposition": f'{disposition}; filename="person.{SUFFIX[format]}"'}
    if policy := answer.headers.get("content-security-policy"):
        headers["Content-Security-Policy"] = policy  # the page's own: its one stylesheet is inline
    return Response(answer.content, media_type=EXPORT_FORMATS[format], headers=headers)
