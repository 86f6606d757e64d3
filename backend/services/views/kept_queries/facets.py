"""The facets of a kept query's filters: for a filter `FILTER (!BOUND(?param_x) || EXISTS { … })`, the values
of the parameter each row's anchor (the one column the EXISTS mentions) has, kept as pairs so a filtered page
is an index lookup."""

from __future__ import annotations

import hashlib
import json

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX
from segb_server.backend.services.views.delta import Delta, Fact
from segb_server.backend.services.views.kept_queries.delta_joins import DeltaJoin
from segb_server.backend.services.views.kept_queries.keys import (
    BRANCHES_PER_QUERY,
    VALUES_PER_QUERY,
    PatternMatch,
    narrowing,
)
from segb_server.backend.services.views.kept_queries.plan import ReportPlan
from segb_server.backend.services.views.kept_queries.plan_parts import FacetFilter, Pattern
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.terms import term_text

FACETS_PREFIX = "report_facets_"  # the tables of facets' pairs (`facet_table`), in the kept rows' databases


class FacetPairs:
    """The (anchor, value) pairs of a facet filter that new triples add. A facet's EXISTS bodies are joins of
    triple patterns with no negation, so its pairs only grow as triples arrive: the new ones are those where a
    new triple matches one of a body's patterns, found by binding that pattern to the triple and joining the
    rest of the body (the delta rule). A post's cost is what its own triples join with, never every pair of the
    anchor they reach (a robot's: every activity it ever performed)."""

    def __init__(self, plan: ReportPlan, facet: FacetFilter) -> None:
        self.plan = plan
        self.facet = facet
        self.parameter = f"?{PARAMETER_VARIABLE_PREFIX}{facet.parameter}"
        self._matches = [(PatternMatch(plan, pattern), body) for body in facet.bodies for pattern in body]
        # What the pairs depend on: the anchor, and each body's patterns and the values its groups allow
        self._signature = (
            "facet",
            facet.anchor,
            tuple(
                (tuple((p.subject, tuple(sorted(p.predicates)), p.object) for p in body),
                 tuple(sorted(plan.allowed_in(body).items())))
                for body in facet.bodies
            ),
        )  # fmt: skip
        # Each body from each of its patterns, as followed among a batch's triples (`delta_joins.py`).
        self._joins = {
            (match.pattern, body): DeltaJoin(
                _without(body, match.pattern),
                sorted(match.pattern.variables()),
                [facet.anchor, self.parameter],
                plan.allowed_in(body),
            )
            for match, body in self._matches
        }

    def all_pairs(self, store: Store) -> list[tuple[str, str]]:
        """Every pair in the store (one query per EXISTS body)."""
        return sorted({pair for body in self.facet.bodies for pair in self._pairs(store, body, "")})

    def new_pairs(self, delta: Delta, store: Store) -> list[tuple[str, str]]:
        """The pairs in which one of the new triples takes part: worked out once a batch for every kept query with
        the same filter (the timeline's kinds of activity share theirs)."""
        return delta.shared(self._signature, lambda: self._new_pairs(delta, store))

    def _new_pairs(self, delta: Delta, store: Store) -> list[tuple[str, str]]:
        """The pairs in which one of the new triples (just added to the store) takes part: one branch per body
        pattern the triples match, bound to them, asked together (BRANCHES_PER_QUERY a query). Kept queries
        sharing a filter (the reports and the timeline's kinds filter by the same robot and human) ask the same
        text, which the batch answers once."""
        branches: list[str] = []  # asked together
        alone: list[str] = []  # binding a literal: asked one by one (Virtuoso 7 fails such a branch in a UNION)
        pairs: set[tuple[str, str]] = set()
        for match, body in self._matches:
            facts: list[Fact] = self._joined_in_delta(delta, match, body, pairs)
            if not facts:
                continue
            names = sorted(match.pattern.variables())
            literal = any(match.binds_literal(fact, tuple(names)) for fact in facts)
            rows = sorted({"(" + " ".join(match.text(fact, name) for name in names) + ")" for fact in facts})
            for start in range(0, len(rows), VALUES_PER_QUERY):
                values = f"VALUES ({' '.join(names)}) {{ {' '.join(rows[start : start + VALUES_PER_QUERY])} }} "
                (alone if literal else branches).append(f"{{ {self._where(body, values)} }}")
        queries = [[branch] for branch in alone]
        queries += [branches[at : at + BRANCHES_PER_QUERY] for at in range(0, len(branches), BRANCHES_PER_QUERY)]
        for group in queries:
            query = self._select(" UNION ".join(group))
            pairs.update(delta.answer(query, lambda text: self._answered(store, text)))
        return sorted(pairs)

    def _joined_in_delta(
        self, delta: Delta, match: PatternMatch, body: tuple[Pattern, ...], pairs: set[tuple[str, str]]
    ) -> list[Fact]:
        """Adds to `pairs` those of the new triples `match` takes whose join with the rest of `body` stays among
        the batch's own resources (`delta_joins.py`); returns the triples whose join needs the store."""
        if match.pattern.subject == match.pattern.object:  # `?x p ?x`: left to the store
            return match.facts(delta)
        join = self._joins[(match.pattern, body)]
        names = sorted(match.pattern.variables())
        asked = []
        for fact in match.facts(delta):
            found = join.run(delta, [match.text(fact, name) for name in names])
            if found is None:
                asked.append(fact)
            else:
                pairs.update((anchor, value) for anchor, value in found)
        return asked

    def _pairs(self, store: Store, body: tuple[Pattern, ...], values: str) -> set[tuple[str, str]]:
        return self._answered(store, self._select(self._where(body, values)))

    def _where(self, body: tuple[Pattern, ...], values: str) -> str:
        patterns = " ".join(pattern.sparql() for pattern in body)
        return f"{values}{narrowing(self.plan, body)}{patterns}"

    def _select(self, where: str) -> str:
        return f"SELECT DISTINCT {self.facet.anchor} {self.parameter} WHERE {{ {where} }}"

    def _answered(self, store: Store, query: str) -> set[tuple[str, str]]:
        found = set()
        for row in select(store, query).rows:
            anchor, value = row.get(self.facet.anchor[1:]), row.get(self.parameter[1:])
            if anchor is not None and value is not None:
                found.add((term_text(anchor), term_text(value)))
        return found


def _without(body: tuple[Pattern, ...], pattern: Pattern) -> list[Pattern]:
    rest = list(body)
    rest.remove(pattern)
    return rest


def facet_table(plan: ReportPlan, facet: FacetFilter) -> str:
    """The table of a facet's (value, anchor) pairs, named by what the pairs depend on (its anchor, its bodies'
    patterns and the values their groups allow): the reports of one database whose facets have the same
    patterns keep their pairs once (the timeline's kinds: one table where eight held the same pairs)."""
    bodies = [
        [[[p.subject, sorted(p.predicates), p.object] for p in body],
         [[variable, sorted(values)] for variable, values in sorted(plan.allowed_in(body).items())]]
        for body in facet.bodies
    ]  # fmt: skip
    described = [facet.anchor, bodies]
    return FACETS_PREFIX + hashlib.sha256(json.dumps(described).encode()).hexdigest()[:16]


def facet_patterns(plan: ReportPlan) -> frozenset[Pattern]:
    """The patterns of facet filters' EXISTS bodies: they decide which rows a filter keeps (the facets table),
    never what a row holds."""
    return frozenset(pattern for facet in plan.facet_filters for body in facet.bodies for pattern in body)
