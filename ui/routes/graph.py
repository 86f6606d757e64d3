"""/kg-graph (the interactive knowledge-graph explorer) and /explain (the causal story of one event).

The browser fetches graph data from this UI server (`/kg-graph/data`, `/kg-graph/resource`), which asks the
API with the viewer's token: the page's CSP allows connections to its own origin only, and the token stays
in an HttpOnly cookie.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from segb_server.ui.choices import participant_choices
from segb_server.ui.findings_marks import findings_about
from segb_server.ui.namesakes import tell_apart
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import query_values
from segb_server.ui.vocabulary import current

router = APIRouter()

GRAPH_PARAMETERS = ("limit", "robot", "since", "until", "types", "focus", "depth", "q")
NAMED_KINDS = ("robot", "human", "model")  # kinds whose namesakes are told apart in the drawing


def graph_parameters(request: Request) -> dict[str, str]:
    values = query_values(request, GRAPH_PARAMETERS)
    if request.query_params.getlist("kind"):
        values["types"] = ",".join(request.query_params.getlist("kind"))
    return values


@router.get("/kg-graph", response_class=HTMLResponse)
async def graph_page(request: Request) -> HTMLResponse:
    parameters = graph_parameters(request)
    choices = await participant_choices(request)
    data_query = request.url.query
    return render(
        request,
        "kg-graph.html",
        {
            "parameters": parameters,
            "chosen_kinds": set(request.query_params.getlist("kind")),
            "choices": choices,
            "kinds": current().kinds,
            "prefixes": current().prefixes,
            "data_src": "/kg-graph/data" + (f"?{data_query}" if data_query else ""),
        },
    )


async def _relay_json(request: Request, path: str, params: dict[str, str]) -> Response:
    """The API's JSON as is: thousands of nodes need not be decoded and encoded again here."""
    answer = await backend(request).request("GET", path, token=token(request), params=params)
    return Response(answer.content, media_type="application/json")


@router.get("/kg-graph/data")
async def graph_data(request: Request) -> Response:
    answer = await backend(request).get_json("/graph", token=token(request), params=graph_parameters(request))
    return JSONResponse(with_namesakes_told_apart(answer))


def with_namesakes_told_apart(graph: dict[str, Any]) -> dict[str, Any]:
    """Two robots called the same, two people called Maria, one model name registered by several robots: their
    labels get what tells them apart. Other kinds (messages saying the same words) keep their text."""
    people = [node for node in graph["nodes"] if node.get("kind") in NAMED_KINDS]
    names = tell_apart({node["id"]: str(node.get("label") or node["id"]) for node in people})
    for node in people:
        node["label"] = str(names[node["id"]])
    return graph


@router.get("/kg-graph/resource")
async def graph_resource(request: Request, iri: str) -> Response:
    return await _relay_json(request, "/resource", {"iri": iri})


@router.get("/explain", response_class=HTMLResponse)
async def explain_page(request: Request, iri: str = "") -> HTMLResponse:
    story = None
    if iri.strip():
        story = await backend(request).get_json("/explain", token=token(request), params={"iri": iri.strip()})
    marks = await findings_about(request, _story_iris(story)) if story else {}
    return render(request, "explain.html", {"iri": iri, "story": story, "marks": marks})


def _story_iris(story: dict[str, Any]) -> list[object]:
    """The nodes a story names: its seed, and each step's activity, messages and emotions."""
    found: list[object] = [story.get("iri")]
    for step in story.get("steps", []):
        found.append(step.get("activity"))
        for key in ("heard", "said", "emotions"):
            found += [item.get("iri") for item in step.get(key) or []]
    return found
