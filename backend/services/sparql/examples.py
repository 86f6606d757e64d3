"""What the query workbench offers: the known prefixes and example queries (the catalog's own among them)."""

from __future__ import annotations

from dataclasses import dataclass

from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.vocabulary import PREFIXES, sparql_prologue

STARTER = "SELECT ?subject ?predicate ?object\nWHERE { ?subject ?predicate ?object }\nLIMIT 100\n"
EXAMPLE_FOLDERS = ("examples", "reports")


@dataclass(frozen=True)
class Example:
    name: str
    title: str
    description: str
    query: str


@dataclass(frozen=True)
class Examples:
    prefixes: dict[str, str]
    prologue: str
    examples: list[Example]


def query_examples(catalog: Catalog) -> Examples:
    """The starter query (every prefix declared), then the catalog's examples and report queries as they
    run for the reports; their `?param_*` variables stay unbound, which switches their filters off."""
    prologue = sparql_prologue()
    starter = Example("starter", "Every triple (first 100)", "Any subject, predicate and object.", prologue + STARTER)
    shipped = [
        Example(query.name, query.title, query.description, query.text)
        for folder in EXAMPLE_FOLDERS
        for query in catalog.under(folder)
    ]
    return Examples(prefixes=dict(PREFIXES), prologue=prologue, examples=[starter, *shipped])
