"""Robots and humans to pick from in filter forms, from the participants report (namesakes told apart)."""

from __future__ import annotations

from fastapi import Request

from segb_server.ui.namesakes import tell_apart
from segb_server.ui.pages import backend, token


async def participant_choices(request: Request) -> dict[str, dict[str, str]]:
    table = await backend(request).get_json("/reports/participants", token=token(request), params={"limit": 1000})
    robots: dict[str, str] = {}
    humans: dict[str, str] = {}
    for row in table["rows"]:
        robots[row["robot"]] = row.get("robotName") or row["robot"]
        humans[row["human"]] = row.get("humanName") or row["human"]
    return {"robots": _by_name(robots), "humans": _by_name(humans)}


def _by_name(choices: dict[str, str]) -> dict[str, str]:
    shown = {iri: str(name) for iri, name in tell_apart(choices).items()}
    return dict(sorted(shown.items(), key=lambda item: item[1].casefold()))
