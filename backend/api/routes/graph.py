"""The knowledge graph for drawing (GET /graph), one resource in full (GET /resource), and the causal
explanation of one message, activity, emotion or state (GET /explain)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.responses import FastJSONResponse
from segb_server.backend.services.graph.service import MAX_NODES, GraphRequest, parse_types
from segb_server.backend.services.sparql.catalog import Parameter, check_window, to_term
from segb_server.backend.services.values import iso_time

router = APIRouter(tags=["graph"])

Iri = Annotated[str, Query(description="Absolute IRI of a resource")]


def _iri(name: str, value: str | None) -> str | None:
    """Validated like a report filter: 422 naming the parameter when it is not an absolute IRI."""
    return None if not value else _required_iri(name, value)


def _required_iri(name: str, value: str) -> str:
    return to_term(Parameter(name, "iri"), value).value


def _time(name: str, value: str | None) -> str | None:
    return None if not value else iso_time(to_term(Parameter(name, "dateTime"), value).value)


@router.get(
    "/graph",
    summary="Nodes and edges of the knowledge graph",
    description=(
        "`{nodes: [{id, label, kind, types, time?}], edges: [{id, source, target, predicate, label}], truncated, "
        "total_nodes, matches, through}`. `kind` is robot, human, activity, message, emotion, model, shared-event, "
        "state or other. Filters: `robot` (its activities, states and what they touched), `since`/`until`, `types` "
        "(comma-separated kinds or classes), `focus` with `depth` (neighbourhood), `q` (label search: matches "
        "and their neighbours; `matches` lists the hits). Most relevant nodes first; `truncated` when `limit` "
        "cut some off; `through`, the journal entry the drawing includes (a `GET /graph/stream` event newer than "
        "it means: fetch again). Literals are not nodes: read them with `/resource`."
    ),
)
async def graph(
    services: ServicesDep,
    principal: Auditor,
    limit: Annotated[int, Query(ge=1, le=MAX_NODES)] = 1500,
    robot: str | None = None,
    since: str | None = None,
    until: str | None = None,
    types: Annotated[str | None, Query(description="e.g. `robot,human` or `oro:Robot`")] = None,
    focus: str | None = None,
    depth: Annotated[int, Query(ge=0, le=6)] = 1,
    q: Annotated[str | None, Query(max_length=200)] = None,
) -> FastJSONResponse:
    request = GraphRequest(
        limit=limit,
        robot=_iri("robot", robot),
        since=_time("since", since),
        until=_time("until", until),
        types=parse_types(types),
        focus=_iri("focus", focus),
        depth=depth,
        q=q.strip() if q and q.strip() else None,
    )
    check_window(since, until)  # after `_time` said each is a time
    # A FastJSONResponse skips FastAPI's per-value encoding pass, which costs more than the query on big graphs;
    # made in the worker thread, so encoding a view of a megabyte does not hold the event loop either.
    return await run_in_threadpool(lambda: FastJSONResponse(services.graph.graph(request)))


@router.get("/resource", summary="Every triple about one resource, both directions, with labels")
async def resource(iri: Iri, services: ServicesDep, principal: Auditor) -> dict[str, Any]:
    return await run_in_threadpool(services.graph.resource, _required_iri("iri", iri))


@router.get(
    "/explain",
    summary="Why did the robot do that? The causal chain around a message, activity, emotion or state",
    description=(
        "Walks `segb:triggeredByActivity`, `segb:triggeredByEntity`, `prov:wasGeneratedBy`, "
        "`segb:producedEntityResult`, `prov:wasDerivedFrom` backwards and forwards from the resource, and tells "
        "each activity as a step in time order with what was heard and said, the models used, the emotions "
        "read and the shared events and humans it was about (a shared event's seeds are the activities about "
        "it). `role` is cause, seed, effect or related. 404 when "
        "nothing is known about the IRI. Read from the graph index, like `/graph`: a post's steps appear once "
        "the views include it (`reports_lag` in `/healthz/ready`)."
    ),
)
async def explain(iri: Iri, services: ServicesDep, principal: Auditor) -> dict[str, Any]:
    return await run_in_threadpool(services.explain.explain, _required_iri("iri", iri))
