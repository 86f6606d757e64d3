"""/kg-graph (the interactive knowledge-graph explorer) and /explain (the causal story of one event).

The browser fetches graph data from this UI server (`/kg-graph/data`, `/kg-graph/resource`), which asks the
API with the viewer's token: the page's CSP allows connections to its own origin only, and the token stays
in an HttpOnly cookie.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from segb_server.ui.choices import participant_choices
from segb_server.ui.display import id_words, is_unnamed, unnamed_label
from segb_server.ui.findings_marks import findings_about
from segb_server.ui.namesakes import tell_apart
from segb_server.ui.pages import backend, render, token
from segb_server.ui.participant_names import MAX_PAIRS, robots_met
from segb_server.ui.query_params import query_values
from segb_server.ui.vocabulary import current

router = APIRouter()

GRAPH_PARAMETERS = ("limit", "robot", "since", "until", "types", "focus", "depth", "q")
NAMED_KINDS = ("robot", "human", "model")  # kinds whose namesakes are told apart in the drawing
NEIGHBOURS = 400  # nodes of a neighbourhood drawn to name a node's unnamed neighbours (as Expand draws it)


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


@router.get("/kg-graph/data")
async def graph_data(request: Request) -> Response:
    return JSONResponse(await readable_graph(request, graph_parameters(request)))


async def readable_graph(request: Request, params: dict[str, str]) -> dict[str, Any]:
    """The API's drawing for these parameters, labelled with `with_readable_labels`."""
    client, user_token = backend(request), token(request)
    answer, participants = await asyncio.gather(
        client.get_json("/graph", token=user_token, params=params),
        client.get_json("/reports/participants", token=user_token, params={"limit": MAX_PAIRS}),
    )
    return with_readable_labels(answer, robots_met(participants["rows"]))


def with_readable_labels(graph: dict[str, Any], humans_met: Mapping[str, str]) -> dict[str, Any]:
    """Labels that name, not ids. Two people called Maria are told apart by the robots that met them, one model
    name registered by several robots by the robots that used it; a node the log gave no name (a state, a
    property value) is told by its robot, kind and time, or by the words of its IRI without the generated id.
    Other kinds (messages saying the same words) keep their text."""
    nodes = {node["id"]: node for node in graph["nodes"]}
    robots_of = _robots_around(graph, nodes)
    hints = {**{iri: ", ".join(sorted(robots, key=str.casefold)) for iri, robots in robots_of.items()}, **humans_met}
    for node in nodes.values():
        if node.get("kind") != "robot" and is_unnamed(node["id"], node.get("label")):
            node["label"] = unnamed_label(node, robots_of.get(node["id"], set()))
    people = [node for node in nodes.values() if node.get("kind") in NAMED_KINDS]
    names = tell_apart({node["id"]: str(node.get("label") or node["id"]) for node in people}, hints)
    for node in people:
        node["label"] = str(names[node["id"]])
    return graph


def _robots_around(graph: dict[str, Any], nodes: Mapping[str, Mapping[str, Any]]) -> dict[str, set[str]]:
    """Each node's robots: those it has an edge to, else those of its neighbours (a model used by activities),
    else the robot whose namespace its IRI is in."""
    robot_names = {iri: str(node.get("label")) for iri, node in nodes.items() if node.get("kind") == "robot"}
    neighbours: dict[str, set[str]] = {}
    for edge in graph["edges"]:
        neighbours.setdefault(edge["source"], set()).add(edge["target"])
        neighbours.setdefault(edge["target"], set()).add(edge["source"])
    direct = {iri: {robot_names[n] for n in near if n in robot_names} for iri, near in neighbours.items()}
    # Last, the robot that minted the node's IRI in its own namespace (a model no activity of the drawing used).
    minted = {_namespace(iri): name for iri, name in robot_names.items()}
    return {
        iri: direct.get(iri)
        or {robot for n in neighbours.get(iri, ()) if n not in robot_names for robot in direct.get(n, set())}
        or ({minted[_namespace(iri)]} if _namespace(iri) in minted else set())
        for iri in nodes
    }


def _namespace(iri: str) -> str:
    return iri.rstrip("/#").rsplit("/", 1)[0]


@router.get("/kg-graph/resource")
async def graph_resource(request: Request, iri: str) -> Response:
    """The node's statements for the details panel. A linked resource the log gave no name (a message, a state,
    an emotion reading) gets the label its node has in a drawing of the neighbourhood (its text; its robot, kind
    and time), else the words of its IRI: the panel links by name, the IRI in the link's tooltip."""
    resource = await backend(request).get_json("/resource", token=token(request), params={"iri": iri})
    unnamed = [s for s in resource["outgoing"] + resource["incoming"] if _links_unnamed(s)]
    if unnamed:
        around = await readable_graph(request, {"focus": iri, "depth": "1", "limit": str(NEIGHBOURS)})
        labels = {node["id"]: node["label"] for node in around["nodes"]}
        for statement in unnamed:
            statement["label"] = labels.get(statement["value"]) or id_words(statement["value"])
    return JSONResponse(resource)


def _links_unnamed(statement: Mapping[str, Any]) -> bool:
    """A link to a logged resource whose label is only its IRI's last part (not a vocabulary term: `oro:Human`)."""
    value = str(statement["value"])
    return (
        not statement["is_literal"] and is_unnamed(value, statement.get("label")) and current().compact(value) == value
    )


@router.get("/explain", response_class=HTMLResponse)
async def explain_page(request: Request, iri: str = "") -> HTMLResponse:
    story = None
    if iri.strip():
        story = await backend(request).get_json("/explain", token=token(request), params={"iri": iri.strip()})
    marks = await findings_about(request, _story_iris(story)) if story else {}
    if story:
        story["seed"]["label"] = _seed_name(story)
    return render(request, "explain.html", {"iri": iri, "story": story, "marks": marks})


def _seed_name(story: dict[str, Any]) -> str:
    """The story's subject as the drawing labels it: a state or an emotion reading the log gave no name by its
    robot, kind and time (`ARI's state at 10:00:03.500`), never by its IRI."""
    seed = story["seed"]
    if seed.get("kind") == "activity" or not is_unnamed(seed["iri"], seed.get("label")):
        return str(seed.get("label"))
    steps = [step for step in story.get("steps", []) if step.get("role") == "seed"]
    robots = {str(step["robot"]["label"]) for step in steps if step.get("robot")}
    time = seed.get("time") or next((step["time"] for step in steps if step.get("time")), None)
    return unnamed_label({"id": seed["iri"], "kind": seed.get("kind"), "time": time}, robots)


def _story_iris(story: dict[str, Any]) -> list[object]:
    """The nodes a story names: its seed, and each step's activity, messages and emotions."""
    found: list[object] = [story.get("iri")]
    for step in story.get("steps", []):
        found.append(step.get("activity"))
        for key in ("heard", "said", "emotions"):
            found += [item.get("iri") for item in step.get(key) or []]
    return found
