"""The parts a report's plan is made of: its triple patterns, the filters its parameters switch on, its
aggregates and the NOT EXISTS that exclude rows; and `Unsupported`, for a query the plan cannot follow."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Comparison = Literal["=", ">=", "<="]


class Unsupported(Exception):
    """The report uses something the plan cannot keep current; it is evaluated in full instead."""


@dataclass(frozen=True)
class Pattern:
    """One triple pattern: subject and object are variable names ("?x") or N-Triples terms; `predicates` is the
    set of IRIs it matches (an alternative path gives several). `group` is the scope it belongs to."""

    subject: str
    predicates: frozenset[str]
    object: str
    group: int

    def variables(self) -> set[str]:
        return {term for term in (self.subject, self.object) if term.startswith("?")}

    def sparql(self) -> str:
        predicate = "|".join(f"<{iri}>" for iri in sorted(self.predicates))
        return f"{self.subject} {predicate} {self.object} ."


@dataclass(frozen=True)
class ColumnFilter:
    """`FILTER (!BOUND(?param_x) || ?column <op> ?param_x)`: served as a comparison on a column."""

    parameter: str
    column: str
    op: Comparison


@dataclass(frozen=True)
class FacetFilter:
    """`FILTER (!BOUND(?param_x) || EXISTS { … } || EXISTS { … })`: served from the values each `anchor` (the one
    column the patterns mention) has for the parameter."""

    parameter: str
    anchor: str
    bodies: tuple[tuple[Pattern, ...], ...]


@dataclass(frozen=True)
class Aggregate:
    """`(FUNCTION(DISTINCT? ?argument) AS ?output)`."""

    function: Literal["count", "sample", "min", "max"]
    argument: str
    output: str
    distinct: bool


@dataclass(frozen=True)
class Exclusion:
    """`FILTER NOT EXISTS { … }` in the top group, its body triple patterns alone: `shared` are the variables it
    has in common with the rest of the query (what a solution of the query binds when the body is tried)."""

    patterns: list[Pattern]
    shared: frozenset[str]
