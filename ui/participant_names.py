"""Robots and humans by their display names, for pages that get only their IRIs from the API (the shared-context
queue, the graph's drawing). Two people called Maria are told apart by the robots that met them, not by their IRIs."""

from __future__ import annotations

import asyncio
from collections.abc import Iterable, Mapping

from fastapi import Request

from segb_server.ui.display import short_iri
from segb_server.ui.namesakes import Name, tell_apart
from segb_server.ui.pages import backend, token

MAX_NODES = 20_000  # the API's largest graph answer
MAX_PAIRS = 1000  # robot and human pairs read for the hints (more only refine who met whom)


def robots_met(rows: Iterable[Mapping[str, object]]) -> dict[str, str]:
    """Each human's robots from the participants report's rows, the one that met them most first:
    `{…/ari/v1/human_maria: "ARI, TIAGo"}`."""
    met: dict[str, dict[str, float]] = {}
    for row in rows:
        human, robot = row.get("human"), row.get("robotName") or short_iri(row.get("robot"))
        if human and robot:
            counts = met.setdefault(str(human), {})
            counts[str(robot)] = counts.get(str(robot), 0) + float(str(row.get("interactions") or 0))
    return {
        human: ", ".join(sorted(counts, key=lambda robot: (-counts[robot], robot.casefold())))
        for human, counts in met.items()
    }


async def participant_names(request: Request) -> dict[str, Name]:
    """Every robot and human the graph knows, by display name, namesakes qualified by the robots that met them."""
    client, user_token = backend(request), token(request)
    graph, participants = await asyncio.gather(
        client.get_json("/graph", token=user_token, params={"types": "robot,human", "limit": MAX_NODES}),
        client.get_json("/reports/participants", token=user_token, params={"limit": MAX_PAIRS}),
    )
    labels = {str(node["id"]): str(node.get("label") or short_iri(node["id"])) for node in graph["nodes"]}
    return tell_apart(labels, robots_met(participants["rows"]))
