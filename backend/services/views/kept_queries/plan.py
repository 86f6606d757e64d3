"""What keeping a report current needs, read from its `.rq` file: the triple patterns and which of them are
sure to hold together, the filters its parameters switch on, its sort order, and (for an aggregate) its
groups. Only the row key is declared in the file's header (`# key: ?message`); everything else is derived
from the query itself, so a report stays defined by its `.rq` file alone.

A construct this plan cannot follow makes the report `Unsupported`: it is then served by evaluating the
query in full, never from rows that might be wrong.

The plan's parts are in `plan_parts.py`; `query_walker.py` collects them from rdflib's algebra of the query.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field

from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.sparql.parser import exists_groups, translate_query
from segb_server.backend.services.views.kept_queries.plan_parts import (
    Aggregate,
    ColumnFilter,
    Exclusion,
    FacetFilter,
    Pattern,
    Unsupported,
)
from segb_server.backend.services.views.kept_queries.query_walker import QueryWalker

_KEY = re.compile(r"#\s*key:\s*((?:\?\w+\s*)+)")


@dataclass
class ReportPlan:
    name: str
    key: tuple[str, ...]  # the variables whose values identify a row's key (a group's, for aggregates)
    columns: list[str]
    order: list[str]
    patterns: list[Pattern]
    guaranteed: dict[int, set[int]]  # group → the groups whose mandatory patterns hold whenever it matches
    mandatory: dict[int, list[Pattern]]  # group → its own mandatory patterns
    column_filters: list[ColumnFilter] = field(default_factory=list)
    facet_filters: list[FacetFilter] = field(default_factory=list)
    aggregates: list[Aggregate] = field(default_factory=list)
    group_by: list[str] = field(default_factory=list)  # aggregate reports: the group variables
    branches: dict[int, int] = field(default_factory=dict)  # a UNION branch's or OPTIONAL's group → its parent
    aliases: list[tuple[str, str]] = field(default_factory=list)  # (?x, ?a): BIND made ?x the value of ?a
    # (group, ?x) → the only IRIs ?x may be in that group (its `VALUES ?x { … }` or `FILTER (?x IN (…))`): a
    # triple with another term there matches none of the group's patterns, so it touches no key through them
    narrowed: dict[tuple[int, str], frozenset[str]] = field(default_factory=dict)
    # The patterns every solution matches: the top group's own (none when a sub-select's patterns, whose variables
    # are its own, are among them)
    required: list[Pattern] = field(default_factory=list)
    # The top group's `FILTER NOT EXISTS { … }` of triple patterns alone (and VALUES), each with the variables it
    # shares with the rest of the query: a solution of one that binds only those excludes their values' rows
    exclusions: list[Exclusion] = field(default_factory=list)

    @property
    def is_aggregate(self) -> bool:
        return bool(self.aggregates)

    def unit(self) -> str:
        """The variable (without ?) whose values identify the rows kept: the key, or for an aggregate what its
        one COUNT(DISTINCT …) counts (its contributions are kept by it). Unsupported when there is none."""
        if self.is_aggregate:
            counted = [a for a in self.aggregates if a.function == "count" and a.distinct]
            if len(counted) != 1:
                raise Unsupported("an aggregate report needs one COUNT(DISTINCT ?x) to keep its contributions by")
            return counted[0].argument[1:]
        if len(self.key) != 1:
            raise Unsupported("a report's key is one variable")
        return self.key[0][1:]

    def allowed_in(self, patterns: Iterable[Pattern]) -> dict[str, frozenset[str]]:
        """The only IRIs each variable may be in the groups of `patterns` (their VALUES and `FILTER (?x IN (…))`;
        several of one variable: all hold)."""
        groups = {pattern.group for pattern in patterns}
        allowed: dict[str, frozenset[str]] = {}
        for (group, variable), values in self.narrowed.items():
            if group in groups:
                allowed[variable] = allowed[variable] & values if variable in allowed else values
        return allowed

    def exclusions_of(self, variable: str) -> list[list[Pattern]]:
        """The bodies of the top group's NOT EXISTS that share `variable` alone with the rest of the query: a
        solution of one, with `variable` bound to a value, means no row has that value."""
        return [exclusion.patterns for exclusion in self.exclusions if exclusion.shared == frozenset({variable})]

    def guaranteed_patterns(self, pattern: Pattern) -> list[Pattern]:
        """The patterns that hold in every solution in which `pattern` is matched."""
        return [found for group in self.guaranteed[pattern.group] for found in self.mandatory.get(group, [])]

    def branch_choices(self, pattern: Pattern) -> list[list[Pattern]]:
        """For each UNION branch or OPTIONAL group beside `pattern`'s scopes, its mandatory patterns: the ways a
        solution matching `pattern` may have bound a variable those scopes do not (a BIND of COALESCE over
        optional values, a UNION of ways to reach a human)."""
        chain = self.guaranteed[pattern.group]
        return [
            self.mandatory.get(branch, [])
            for branch, parent in self.branches.items()
            if parent in chain and branch not in chain
        ]


def declared_key(query: CatalogQuery) -> tuple[str, ...]:
    found = _KEY.search(query.text)  # the text opens with its header (a preset's, with its base's)
    if found is None:
        raise Unsupported("no `# key:` line in the header")
    return tuple(found.group(1).split())


def plan_report(query: CatalogQuery) -> ReportPlan:
    """Raise Unsupported when the query holds something the plan cannot keep current."""
    algebra = translate_query(query.text)
    walker = QueryWalker(exists_groups(query.text))
    root = walker.new_group(None)
    walker.visit(algebra, root)
    columns = [f"?{variable}" for variable in algebra["PV"]]
    key = declared_key(query)
    plan = ReportPlan(
        name=query.name,
        key=key,
        columns=columns,
        order=walker.order,
        patterns=walker.patterns,
        guaranteed=walker.guaranteed(),
        mandatory=walker.mandatory,
        column_filters=walker.column_filters,
        facet_filters=walker.facets(columns),
        aggregates=walker.aggregates,
        group_by=walker.group_by,
        branches=walker.branches,
        aliases=walker.aliases,
        narrowed=walker.narrowed,
        required=[] if walker.projections > 1 else walker.mandatory[root],
        exclusions=[] if walker.projections > 1 else walker.exclusions(),
    )
    if plan.is_aggregate:
        if not all(name in plan.group_by or name in {a.output for a in plan.aggregates} for name in columns):
            raise Unsupported("an aggregate report's columns must be its groups and its aggregates")
        if plan.key != tuple(plan.group_by):
            raise Unsupported("the key of an aggregate report is its GROUP BY")
    elif not set(key) <= set(columns):
        raise Unsupported("the key must be among the report's columns")
    if any(column not in columns and column not in plan.group_by for column in plan.order):
        raise Unsupported("it sorts by something that is not a column")
    return plan
