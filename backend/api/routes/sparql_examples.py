"""GET /sparql/examples: the prefixes and example queries a query editor starts from."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.services.sparql.examples import query_examples

router = APIRouter(tags=["sparql"])


class ExamplePublic(BaseModel):
    name: str = Field(examples=["reports/participants"])
    title: str
    description: str
    query: str = Field(description="The query text, ready to send to /sparql.")


class ExamplesPublic(BaseModel):
    prefixes: dict[str, str] = Field(description="Prefix → namespace of the vocabularies robots log with.")
    prologue: str = Field(description="The same prefixes as PREFIX lines, to start a query with.")
    examples: list[ExamplePublic]


@router.get(
    "/sparql/examples",
    response_model=ExamplesPublic,
    summary="Prefixes and example queries",
    description=(
        "The known prefixes (as a map and as PREFIX lines) and example queries: a starter, the catalog's "
        "examples and every report query. Report queries carry `?param_*` variables that stay unbound when "
        "run as they are, which switches their filters off."
    ),
)
async def sparql_examples(services: ServicesDep, principal: Auditor) -> ExamplesPublic:
    found = query_examples(services.catalog)
    return ExamplesPublic(
        prefixes=found.prefixes,
        prologue=found.prologue,
        examples=[ExamplePublic(**vars(example)) for example in found.examples],
    )
