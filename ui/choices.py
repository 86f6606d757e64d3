"""Robots and humans to pick from in filter forms, from the participants report (namesakes told apart)."""

from __future__ import annotations

from fastapi import Request

from segb_server.ui.namesakes import tell_apart
from segb_server.ui.pages import backend, token
from segb_server.ui.participant_names import robots_met


async def participant_choices(request: Request) -> dict[str, dict[str, str]]:
    """`robots` and `humans` by name; `met`: each human's robots, which tell namesakes apart on every page (the
    graph's and the shared contexts' too, `participant_names.py`)."""
    table = await backend(request).get_json("/reports/participants", token=token(request), params={"limit": 1000})
    robots: dict[str, str] = {}
    humans: dict[str, str] = {}
    for row in table["rows"]:
        robots[row["robot"]] = row.get("robotName") or row["robot"]
        humans[row["human"]] = row.get("humanName") or row["human"]
    met = robots_met(table["rows"])
    return {"robots": _by_name(robots), "humans": _by_name(humans, met), "met": met}


def _by_name(choices: dict[str, str], hints: dict[str, str] | None = None) -> dict[str, str]:
    shown = {iri: str(name) for iri, name in tell_apart(choices, hints).items()}
    return dict(sorted(shown.items(), key=lambda item: item[1].casefold()))
