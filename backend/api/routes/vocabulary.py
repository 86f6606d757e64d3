"""GET /vocabulary: the namespaces and kinds the server knows, so a client (the web UI) shows the same names."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from segb_server.backend.reading import NAME_PREDICATES
from segb_server.backend.vocabulary import KINDS, PERSON_CLASSES, PREFIXES, ROBOT_CLASSES

router = APIRouter(tags=["vocabulary"])


class Vocabulary(BaseModel):
    prefixes: dict[str, str] = Field(description="Prefix → namespace IRI, as the reports and the editor use them.")
    kinds: list[str] = Field(description="Kinds of things the graph and reports tell apart, in drawing order.")
    name_predicates: list[str] = Field(
        description="Where a display name is read, best first (the rule of reading every page follows)."
    )
    human_classes: list[str] = Field(description="The classes that make a resource a human.")
    robot_classes: list[str] = Field(description="The classes that make a resource a robot.")


@router.get("/vocabulary", summary="Known namespaces and kinds", response_model=Vocabulary)
async def vocabulary() -> Vocabulary:
    """Public: nothing here depends on the data."""
    return Vocabulary(
        prefixes=PREFIXES,
        kinds=list(KINDS),
        name_predicates=list(NAME_PREDICATES),
        human_classes=sorted(PERSON_CLASSES),
        robot_classes=sorted(ROBOT_CLASSES),
    )
