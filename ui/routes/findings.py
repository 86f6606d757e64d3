"""/findings: what the audit rules find, counted by rule and severity, then listed in time order; kept live."""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from typing import Any
from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response

from segb_server.ui.choices import participant_choices
from segb_server.ui.display import is_unnamed, unnamed_label
from segb_server.ui.namesakes import tell_apart
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_params import query_values

router = APIRouter()

PAGE_FINDINGS = 100
FILTERS = ("robot", "human", "since", "until")
SEVERITIES = ("violation", "warning", "info")


def _filters(request: Request) -> dict[str, Any]:
    """The page's filters as the API takes them: one value each, `rule` and `severity` possibly several."""
    values: dict[str, Any] = dict(query_values(request, FILTERS))
    for name in ("rule", "severity"):
        chosen = [value for value in request.query_params.getlist(name) if value]
        if chosen:
            values[name] = chosen
    return values


@router.get("/findings", response_class=HTMLResponse)
async def findings_page(request: Request) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    filters = _filters(request)
    after = request.query_params.get("after") or None
    params = {**filters, "limit": PAGE_FINDINGS, **({"after": after} if after else {})}
    listing, page, choices = await asyncio.gather(
        client.get_json("/rules", token=user_token),
        client.get_json("/findings", token=user_token, params=params),
        participant_choices(request),
    )
    rules = {rule["id"]: rule for rule in listing["rules"]}
    names = {**choices["robots"], **choices["humans"]}
    return render(
        request,
        "findings.html",
        {
            "rules": rules,
            "page": page,
            "filters": filters,
            "choices": choices,
            "severities": SEVERITIES,
            "after": after,
            "names": names,
            "about": about_names(page["findings"], names),
            "next_href": "?" + urlencode({**filters, "after": page["next"]}, doseq=True) if page["next"] else None,
        },
    )


def about_names(findings: list[dict[str, Any]], participants: Mapping[str, str]) -> dict[str, str]:
    """What each finding is about (its `focus`) by name, as the graph names its node: a robot or a person as the
    filters do; a node the log gave no name (a state, an emotion annotation) by its robot, kind and time; else by
    its label, told apart by robot where several robots' nodes share it (two robots' replies in the same words)."""
    names: dict[str, str] = {}
    labels: dict[str, tuple[str, str]] = {}  # a named focus → its label and its robot's name
    for found in findings:
        focus = str(found["focus"])
        node = found.get("about") or {"id": focus, "kind": "other"}
        robot = participants.get(str(found.get("robot")), "")
        if focus in participants:
            names[focus] = participants[focus]
        elif is_unnamed(focus, node.get("label")):
            node = {**node, "time": node.get("time") or found.get("time")}
            names[focus] = unnamed_label(node, {robot} if robot else set())
        else:
            labels[focus] = (str(node["label"]), robot)
    # One node stands for each label and robot (a robot's replies in the same words share one name); a label
    # whose robot is unknown stays as it is.
    standing: dict[tuple[str, str], str] = {}
    for focus, (label, robot) in labels.items():
        standing.setdefault((label.casefold(), robot), focus)
    told = tell_apart(
        {focus: labels[focus][0] for focus in standing.values() if labels[focus][1]},
        {focus: labels[focus][1] for focus in standing.values()},
    )
    for focus, (label, robot) in labels.items():
        names[focus] = str(told.get(standing[(label.casefold(), robot)], label))
    return names


@router.get("/findings/download.{fmt}")
async def download_findings(request: Request, fmt: str) -> Response:
    """The findings as a file, fetched with the viewer's token (the browser never talks to the API)."""
    if fmt not in ("csv", "json"):
        return Response("Downloads are .csv or .json", status_code=404, media_type="text/plain")
    params = {**_filters(request), "limit": 1000, "format": fmt}
    answer = await backend(request).request("GET", "/findings", token=token(request), params=params)
    return Response(
        answer.content,
        media_type=answer.headers.get("content-type", "application/octet-stream"),
        headers={"Content-Disposition": f'attachment; filename="findings.{fmt}"'},
    )
