"""Reports kept as rows, current with each applied journal step (each report is one `Projection`).

For every triple pattern of a report that a new triple matches, the report's own patterns that are sure to
hold with it lead back to the row keys it can change (one small bound query); the report's query is then run
again for just those keys and their rows replaced. OPTIONAL, FILTER, EXISTS and BIND need no special case:
the rows of a key are always the query's own answer for that key. A report is first built by one full
evaluation, in the background; until then, and for reports the plan cannot follow, requests are answered by
evaluating the query in full.
"""

from __future__ import annotations

import hashlib
import logging
import re
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, replace

from pyoxigraph import Literal, Quad, RdfFormat, Triple, parse

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.views.materialized.plan import (
    FacetFilter,
    Pattern,
    ReportPlan,
    Unsupported,
    plan_report,
)
from segb_server.backend.services.views.materialized.rows import Layout, Page, ReportRows, Row
from segb_server.backend.store.base import Store, Term, select
from segb_server.backend.store.sparql_text import code_only
from segb_server.backend.store.terms import bind_rows, bind_values, term_text

logger = logging.getLogger("segb.reports")

PLAN_VERSION = "4"  # bump when the stored layout changes: every report is then built again
VALUES_PER_QUERY = 300
BRANCHES_PER_QUERY = 12  # key-finding chains asked in one query
CHANGES_KEPT = 20_000


class ReportMaintainer:
    """The reports kept as rows: one `ReportProjection` each, run by the `Projector`."""

    def __init__(self, store: Store, rows: ReportRows) -> None:
        self.store = store
        self.rows = rows
        self.reports: dict[str, ReportProjection] = {}  # by report name; a preset shares its base's
        self.unsupported: dict[str, str] = {}
        self._by_source: dict[tuple[str, tuple[tuple[str, str], ...]], ReportProjection] = {}

    def add(self, query: CatalogQuery) -> None:
        """Keep `query` current (or note why it cannot be, once, at start-up). A query with the text and the
        parameters of one already kept (a `same-as` preset: only its defaults differ, and those are bound at
        request time) is served from the same rows, kept once."""
        source = (query.text, tuple(sorted((name, p.type) for name, p in query.parameters.items())))
        if (kept := self._by_source.get(source)) is not None:
            self.reports[query.name] = kept
            return
        try:
            projection = _projection(query, plan_report(query), self.store, self.rows)
        except Unsupported as reason:
            self.unsupported[query.name] = str(reason)
            logger.warning("report %s is evaluated in full on every request: %s", query.name, reason)
            return
        self.reports[query.name] = self._by_source[source] = projection

    def projections(self) -> list[ReportProjection]:
        """Every projection once, for the projector (presets share theirs)."""
        return list(self._by_source.values())

    def drop_unkept(self) -> None:
        """Drop the rows of reports no longer kept (removed from the catalog, or become a preset)."""
        kept = self.projections()
        dropped = self.rows.drop_unkept({t for p in kept for t in p.layout.tables}, {p.name for p in kept})
        if dropped:
            logger.info("dropped the rows of reports no longer kept: %s", ", ".join(dropped))

    def served(self) -> dict[str, list[str]]:
        """Each projection's name → the reports its rows serve: its own, and the presets sharing them."""
        served: dict[str, list[str]] = {}
        for name, projection in self.reports.items():
            served.setdefault(projection.name, []).append(name)
        return served

    def page(self, name: str, bound: dict[str, Term | None], limit: int, offset: int, after: str | None) -> Page | None:
        """A page served from the rows, or None while the report is not (or cannot be) kept as rows."""
        projection = self.reports.get(name)
        if projection is None or not projection.ready:
            return None
        # Read before the rows: a change committed meanwhile is announced again to a reader resuming from here
        # (one refresh too many), never missed.
        last_event_id = self.rows.last_change()
        return replace(self.rows.page(projection.layout, bound, limit, offset, after), last_event_id=last_event_id)


class ReportProjection:
    """One report kept as rows: its layout, the variable its rows are replaced by, and its queries."""

    def __init__(self, layout: Layout, unit: str, text: str, fingerprint: str, store: Store, rows: ReportRows):
        self.layout = layout
        self.unit = unit  # variable name (no ?) whose values the rows are replaced by
        self.fingerprint = fingerprint
        self.store = store
        self.rows = rows
        self.name = layout.plan.name
        self.ready = False
        plan = layout.plan
        # The query whose answer the rows are (for an aggregate: before grouping), parameters left unbound.
        self.text = bind_values(text, {PARAMETER_VARIABLE_PREFIX + p: None for p in layout.parameters})
        self.keys = KeyFinder(plan, unit, ignored=_facet_patterns(plan))
        self.facets = [FacetPairs(plan, facet) for facet in plan.facet_filters]

    def stored_through(self) -> int | None:
        fingerprint, through = self.rows.state(self.name)
        if fingerprint != self.fingerprint:
            return None
        self.rows.create(self.layout, fresh=False)
        return through

    def follow(self) -> int | None:
        fingerprint, through = self.rows.state(self.name)
        return through if fingerprint == self.fingerprint else None

    def prepared(self) -> None:
        pass  # pages are read from the rows as they are

    def build(self, through: int) -> None:
        self.rows.create(self.layout, fresh=True)
        rows = self._evaluate(None)
        self.rows.replace(self.layout, rows, rows, through)
        for delta in self.facets:
            self.rows.add_facets(self.layout, delta.facet.parameter, delta.all_pairs(self.store))
        self.rows.set_state(self.name, self.fingerprint, through)
        logger.info("report %s built: %d keys", self.name, len(rows))

    def clear(self, through: int) -> None:
        self.rows.clear(self.layout)
        self.rows.set_state(self.name, self.fingerprint, through)

    def update(self, quads: list[Quad], through: int) -> None:
        # The store is asked everything first, then the rows change in one transaction: the reports of a remote
        # store are updated side by side, and take turns only for writing.
        replaced: list[str] = []
        rows: dict[str, list[Row]] = {}
        facets: list[tuple[FacetFilter, list[tuple[str, str]]]] = []
        if quads:
            replaced = sorted(self.keys.units(quads, self.store))
            rows = self._evaluate(replaced) if replaced else {}
            facets = [(delta.facet, pairs) for delta in self.facets if (pairs := delta.new_pairs(quads, self.store))]
        with self.rows.db.writing():
            if replaced:
                self.rows.replace(self.layout, replaced, rows, through)
            for facet, pairs in facets:
                self.rows.add_facets(self.layout, facet.parameter, pairs)
            if quads:
                self.rows.prune_changes(CHANGES_KEPT)
            self.rows.set_state(self.name, self.fingerprint, through)
        if replaced:
            self.rows.changed.notify()

    # --- queries -------------------------------------------------------------------------------------

    def _evaluate(self, units: list[str] | None) -> dict[str, list[Row]]:
        """The report's rows grouped by unit: for `units` only, or (None) for all."""
        chunks: list[list[str] | None] = [None] if units is None else _slices(units, VALUES_PER_QUERY)
        grouped: dict[str, list[Row]] = {unit: [] for unit in units or []}
        for chunk in chunks:
            bound = (
                self.text
                if chunk is None
                else bind_rows(self.text, [self.unit], [[_term(unit)] for unit in chunk], wrap=self.store.wraps_values)
            )
            for row in select(self.store, bound).rows:
                unit = row.get(self.unit)
                if unit is not None:
                    grouped.setdefault(term_text(unit), []).append(row)
        return grouped


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
        self._patterns: dict[str, list[tuple[Pattern, tuple[Pattern, ...]]]] = {}
        for body in facet.bodies:
            for pattern in body:
                for predicate in pattern.predicates:
                    self._patterns.setdefault(predicate, []).append((pattern, body))

    def all_pairs(self, store: Store) -> list[tuple[str, str]]:
        """Every pair in the store (one query per EXISTS body)."""
        return sorted({pair for body in self.facet.bodies for pair in self._pairs(store, body, "")})

    def new_pairs(self, quads: list[Quad], store: Store) -> list[tuple[str, str]]:
        """The pairs in which one of `quads` (just added to the store) takes part."""
        matched: dict[tuple[Pattern, tuple[Pattern, ...]], list[Quad]] = {}
        for quad in quads:
            for pattern, body in self._patterns.get(quad.predicate.value, ()):
                if _fits(self.plan, pattern, quad):
                    matched.setdefault((pattern, body), []).append(quad)
        pairs: set[tuple[str, str]] = set()
        for (pattern, body), matches in matched.items():
            names = sorted(pattern.variables())
            rows = sorted({tuple(term_text(_bind(pattern, quad)[name]) for name in names) for quad in matches})
            for start in range(0, len(rows), VALUES_PER_QUERY):
                values = " ".join("(" + " ".join(row) + ")" for row in rows[start : start + VALUES_PER_QUERY])
                pairs.update(self._pairs(store, body, f"VALUES ({' '.join(names)}) {{ {values} }} "))
        return sorted(pairs)

    def _pairs(self, store: Store, body: tuple[Pattern, ...], values: str) -> set[tuple[str, str]]:
        patterns = " ".join(pattern.sparql() for pattern in body)
        where = f"{values}{_narrowing(self.plan, body)}{patterns}"
        found = set()
        for row in select(store, f"SELECT DISTINCT {self.facet.anchor} {self.parameter} WHERE {{ {where} }}").rows:
            anchor, value = row.get(self.facet.anchor[1:]), row.get(self.parameter[1:])
            if anchor is not None and value is not None:
                found.add((term_text(anchor), term_text(value)))
        return found


class KeyFinder:
    """The units (values of `?unit`, as N-Triples text) that new triples may change, for one plan. The chains from
    each of the plan's patterns to the unit are found once, when the report is planned (Unsupported when a
    pattern has none): a post then costs only the matching and the queries. Triples matching only `ignored`
    patterns change no unit."""

    def __init__(self, plan: ReportPlan, unit: str, ignored: frozenset[Pattern] = frozenset()) -> None:
        self.plan = plan
        self.unit = unit
        self.target = f"?{unit}"
        self._leads: dict[str, list[_Lead]] = {}
        for pattern in plan.patterns:
            lead = _Lead(pattern, [] if self.target in pattern.variables() else _chains(plan, pattern, self.target))
            if pattern not in ignored:
                for predicate in pattern.predicates:
                    self._leads.setdefault(predicate, []).append(lead)

    def units(self, quads: list[Quad], store: Store) -> set[str]:
        matched: dict[_Lead, list[Quad]] = {}
        for quad in quads:
            for lead in self._leads.get(quad.predicate.value, ()):
                if _fits(self.plan, lead.pattern, quad):
                    matched.setdefault(lead, []).append(quad)
        units: set[str] = set()
        branches: list[str] = []  # asked together
        alone: list[str] = []  # asked one by one
        for lead, matches in matched.items():
            bindings = [_bind(lead.pattern, quad) for quad in matches]
            if not lead.chains:
                units.update(term_text(binding[self.target]) for binding in bindings if self.target in binding)
                continue
            # One branch per chain, each opening with its own VALUES: they must bind the chain's own group (a BIND
            # in a UNION branch would not see VALUES outside it, and the branch would reach every unit of the store).
            for chain in lead.chains:
                names = chain.names
                rows = list({tuple(term_text(binding[n]) for n in names): binding for binding in bindings}.values())
                for start in range(0, len(rows), VALUES_PER_QUERY):
                    chunk = rows[start : start + VALUES_PER_QUERY]
                    values = " ".join("(" + " ".join(term_text(binding[n]) for n in names) + ")" for binding in chunk)
                    branch = f"{{ VALUES ({' '.join(names)}) {{ {values} }} {chain.steps} }}"
                    # Virtuoso 7 fails a UNION whose branch binds a literal ("Unknown language in
                    # RDF_LANGUAGE_OF_OBJ"): such a branch is asked alone.
                    has_literal = any(isinstance(binding[n], Literal) for binding in chunk for n in names)
                    (alone if has_literal else branches).append(branch)
        # The others together: a remote store costs a round trip per query, and a post touches a handful of them.
        queries = [[branch] for branch in alone]
        queries += [branches[at : at + BRANCHES_PER_QUERY] for at in range(0, len(branches), BRANCHES_PER_QUERY)]
        for group in queries:
            union = " UNION ".join(group)
            answer = select(store, f"SELECT DISTINCT {self.target} WHERE {{ {union} }}")
            units.update(term_text(row[self.unit]) for row in answer.rows if self.unit in row)
        return units


@dataclass(frozen=True)
class _Chain:
    steps: str  # the SPARQL steps from the pattern's variables to the unit
    names: tuple[str, ...]  # the pattern's variables the steps go on from (bound by VALUES)


@dataclass(frozen=True, eq=False)
class _Lead:
    """A pattern, and the chains from its variables to the unit (none: the pattern holds the unit itself)."""

    pattern: Pattern
    chains: list[_Chain]


def _chains(plan: ReportPlan, pattern: Pattern, target: str) -> list[_Chain]:
    chains = []
    for path in paths(plan, pattern, target):
        # Only the variables the chain goes on from: a chain from a triple's subject needs no VALUES of its
        # object, and leaving a literal object out lets the branch join the others' UNION.
        names = sorted(name for name in pattern.variables() if _mentions(path, name)) or sorted(pattern.variables())
        chains.append(_Chain(" ".join(path), tuple(names)))
    return chains


def _mentions(path: list[str], variable: str) -> bool:
    """Whether a chain's steps use `variable` (`?t` is not in `?text`)."""
    used = re.compile(re.escape(variable) + r"(?![A-Za-z0-9_])")
    return any(used.search(step) for step in path)


def _fits(plan: ReportPlan, pattern: Pattern, quad: Quad) -> bool:
    """A triple fits a pattern when its terms equal the pattern's constants, and are among the values its group
    allows a variable (e.g. `?target a ?class` where `VALUES ?class { … }` lists the classes of people: the
    types of every other resource a post describes touch no key through it)."""
    for position, term in ((pattern.subject, quad.subject), (pattern.object, quad.object)):
        if position.startswith("?"):
            allowed = plan.narrowed.get((pattern.group, position))
            if allowed is not None and term_text(term) not in allowed:
                return False
        elif position != term_text(term):
            return False
    return True


def _bind(pattern: Pattern, quad: Quad) -> dict[str, Term]:
    bound: dict[str, Term] = {}
    for position, term in ((pattern.subject, quad.subject), (pattern.object, quad.object)):
        if position.startswith("?"):
            bound[position] = term  # type: ignore[assignment]
    return bound


def paths(plan: ReportPlan, start: Pattern, target: str) -> list[list[str]]:
    """Chains of SPARQL steps from `start`'s variables to `target`, each made of patterns that hold whenever
    `start` is matched (one chain per UNION branch it may have come through) and of BIND aliases. Unsupported
    when there is none."""
    base = [pattern for pattern in plan.guaranteed_patterns(start) if pattern is not start]
    # From the subject first: a triple's object is often a hub (a robot, a model, a human), and a chain from it
    # reaches every unit of that hub, where a chain from the subject reaches the units of this one triple.
    for sources in _sources(start):
        found = _shortest(sources, base, plan.aliases, target)
        if found is not None:
            return [found]
    chains = [
        chain
        for branch in plan.branch_choices(start)
        for sources in _sources(start)[-1:]
        if (chain := _shortest(sources, base + branch, plan.aliases, target))
    ]
    if not chains:
        raise Unsupported(f"no path from {start.sparql()} to {target}")
    return chains


def _sources(start: Pattern) -> list[set[str]]:
    """The variables a chain may start from, tried in turn: the subject alone, then any of them."""
    subject_only = [{start.subject}] if start.subject.startswith("?") and len(start.variables()) > 1 else []
    return [*subject_only, start.variables()]


def _shortest(
    sources: set[str], usable: list[Pattern], aliases: list[tuple[str, str]], target: str
) -> list[str] | None:
    """Breadth first over variables from `sources`: a pattern joins its variables; an alias binds one from the
    other."""
    frontier: deque[tuple[str, list[str]]] = deque((variable, []) for variable in sorted(sources))
    seen = set(sources)
    while frontier:
        variable, path = frontier.popleft()
        if variable == target:
            return path
        steps = [(other, pattern.sparql()) for pattern in usable if variable in pattern.variables()
                 for other in pattern.variables() - {variable}]  # fmt: skip
        steps += [(b if a == variable else a, f"BIND ({variable} AS {b if a == variable else a})")
                  for a, b in aliases if variable in (a, b)]  # fmt: skip
        for other, step in steps:
            if other not in seen:
                seen.add(other)
                frontier.append((other, [*path, step]))
    return None


def _facet_patterns(plan: ReportPlan) -> frozenset[Pattern]:
    """The patterns of facet filters' EXISTS bodies: they decide which rows a filter keeps (the facets table),
    never what a row holds."""
    return frozenset(pattern for facet in plan.facet_filters for body in facet.bodies for pattern in body)


def _narrowing(plan: ReportPlan, body: tuple[Pattern, ...]) -> str:
    """The VALUES an EXISTS body narrows its variables with (`VALUES ?kind { foaf:Person }`), which its patterns
    alone do not say."""
    groups = {pattern.group for pattern in body}
    return "".join(
        f"VALUES {variable} {{ {' '.join(sorted(allowed))} }} "
        for (group, variable), allowed in sorted(plan.narrowed.items())
        if group in groups
    )


def _slices(items: list[str], size: int) -> list[list[str] | None]:
    return [items[start : start + size] for start in range(0, len(items), size)]


def _term(text: str) -> Term:
    """The term whose N-Triples text is `text` (how units are stored)."""
    term = next(iter(parse(f"<urn:x:s> <urn:x:p> {text} .".encode(), RdfFormat.N_TRIPLES))).object
    assert not isinstance(term, Triple)
    return term


def _projection(query: CatalogQuery, plan: ReportPlan, store: Store, rows: ReportRows) -> ReportProjection:
    if plan.is_aggregate:
        counted = [a for a in plan.aggregates if a.function == "count" and a.distinct]
        if len(counted) != 1:
            raise Unsupported("an aggregate report needs one COUNT(DISTINCT ?x) to keep its contributions by")
        unit = counted[0].argument[1:]
        inputs = dict.fromkeys([*plan.group_by, counted[0].argument, *(a.argument for a in plan.aggregates)])
        text = _before_grouping(query.text, list(inputs))
    else:
        if len(plan.key) != 1:
            raise Unsupported("a report's key is one variable")
        unit = plan.key[0][1:]
        text = query.text
    layout = Layout(f"report_{re.sub(r'[^a-z0-9]', '_', query.name.lower())}", plan, query.parameters)
    # The tables' schema counts too: rows stored in another layout are built again, not read.
    fingerprint = hashlib.sha256("\n".join([PLAN_VERSION, query.text, *layout.schema()]).encode()).hexdigest()
    return ReportProjection(layout, unit, text, fingerprint, store, rows)


_SELECT = re.compile(r"\bSELECT\b.*?\bWHERE\b", re.IGNORECASE | re.DOTALL)
_GROUPING = re.compile(r"\}\s*(GROUP\s+BY\b.*)$", re.IGNORECASE | re.DOTALL)


def _before_grouping(text: str, variables: Iterable[str]) -> str:
    """An aggregate query's rows before grouping: its projection replaced by the groups and the aggregated
    variables, its GROUP BY and ORDER BY left out."""
    code = code_only(text)
    select = _SELECT.search(code)
    grouping = _GROUPING.search(code)
    if select is None or grouping is None:
        raise Unsupported("cannot find the projection and the GROUP BY of the aggregate")
    head = f"SELECT DISTINCT {' '.join(variables)} WHERE"
    return text[: select.start()] + head + text[select.end() : grouping.start(1)]
