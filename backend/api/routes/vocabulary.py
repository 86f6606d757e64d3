"""GET /vocabulary: the namespaces and kinds the server knows, so a client (the web UI) shows the same names."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from segb_server.backend.vocabulary import KINDS, PREFIXES

router = APIRouter(tags=["vocabulary"])


class Vocabulary(BaseModel):
    prefixes: dict[str, str] = Field(description="Prefix → namespace IRI, as the reports and the editor use them.")
    kinds: list[str] = Field(description="Kinds of things the graph and reports tell apart, in drawing order.")


@router.get("/vocabulary", summary="Known namespaces and kinds", response_model=Vocabulary)
async def vocabulary() -> Vocabulary:
    """Public: nothing here depends on the data."""
    return Vocabulary(prefixes=PREFIXES, kinds=list(KINDS))
