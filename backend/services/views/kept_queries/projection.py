"""Queries kept as rows (a report's), current with each applied journal step: each query is one `KeptView`.

For every triple pattern of a query that a new triple matches, the query's own patterns that are sure to hold
with it lead back to the row keys it can change (`keys.py`: one small bound query); the query is then run again
for just those keys and their rows replaced (`rows.py`). OPTIONAL, FILTER, EXISTS and BIND need no special case:
the rows of a key are always the query's own answer for that key. A report is first built by one full
evaluation, in the background; until then, and for reports the plan cannot follow, requests are answered by
evaluating the query in full.
"""

from __future__ import annotations

import hashlib
import logging
import re
from collections.abc import Callable, Iterable
from dataclasses import replace

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.kept_queries.delta_joins import DeltaJoin
from segb_server.backend.services.views.kept_queries.facets import FacetPairs, facet_patterns, facet_table
from segb_server.backend.services.views.kept_queries.keys import VALUES_PER_QUERY, KeyFinder
from segb_server.backend.services.views.kept_queries.layout import Layout, Row
from segb_server.backend.services.views.kept_queries.pages import Page
from segb_server.backend.services.views.kept_queries.plan import ReportPlan, plan_report
from segb_server.backend.services.views.kept_queries.plan_parts import FacetFilter, Unsupported
from segb_server.backend.services.views.kept_queries.rows import KeptRows
from segb_server.backend.store.base import Store, Term, select
from segb_server.backend.store.sparql_text import code_only
from segb_server.backend.store.terms import bind_texts, bind_values, term_text

logger = logging.getLogger("segb.reports")

PLAN_VERSION = "11"  # bump when the stored layout changes: every report is then built again
CHANGES_KEPT = 20_000


class KeptQueries:
    """The reports kept as rows: one `KeptQuery` each, run by the `ViewKeeper`."""

    def __init__(self, store: Store, rows: KeptRows) -> None:
        self.store = store
        self.rows = rows
        self.reports: dict[str, KeptQuery] = {}  # by report name; a preset shares its base's
        self.unsupported: dict[str, str] = {}
        self._by_source: dict[tuple[str, tuple[tuple[str, str], ...]], KeptQuery] = {}

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

    def views(self) -> list[KeptQuery]:
        """Every projection once, for the projector (presets share theirs)."""
        return list(self._by_source.values())

    def drop_unkept(self) -> None:
        """Drop the rows of reports no longer kept (removed from the catalog, or become a preset)."""
        kept = self.views()
        dropped = self.rows.drop_unkept({t for p in kept for t in p.layout.tables}, {p.name for p in kept})
        if dropped:
            logger.info("dropped the rows of reports no longer kept: %s", ", ".join(dropped))

    def columns(self, name: str) -> list[str]:
        """The columns of a kept query's rows, in its SELECT's order (without `?`)."""
        return [column[1:] for column in self.reports[name].layout.plan.columns]

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


class KeptQuery:
    """One report kept as rows: its layout, the variable its rows are replaced by, and its queries."""

    def __init__(self, layout: Layout, unit: str, text: str, fingerprint: str, store: Store, rows: KeptRows):
        self.layout = layout
        self.unit = unit  # variable name (no ?) whose values the rows are replaced by
        self.fingerprint = fingerprint
        self.store = store
        self.rows = rows
        self.name = layout.plan.name
        self.ready = False
        plan = layout.plan
        self.text = text  # the query whose answer the rows are (`kept_text`)
        self.keys = KeyFinder(plan, unit, ignored=facet_patterns(plan))
        self.facets = [FacetPairs(plan, facet) for facet in plan.facet_filters]
        # What every row needs (the query's top-level patterns, their variables narrowed by its VALUES and
        # `IN (…)` lists), as far as it can be joined among a batch's triples from a key the batch introduced:
        # with no solution there, that key has no row to ask the store for.
        start = [f"?{unit}"]
        self._needed = DeltaJoin(plan.required, start, start, plan.allowed_in(plan.required), relaxed=True)
        # What no row may have (a top-level NOT EXISTS about the key alone): a solution among the batch's triples
        # from a key the batch introduced is in the store too, so that key has no row either.
        self._excluded = [
            join
            for body in plan.exclusions_of(f"?{unit}")
            if (join := DeltaJoin(body, start, start, plan.allowed_in(body))).usable
        ]

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
        self.rows.replace(self.layout, rows, rows, through, announce=False)
        for delta in self.facets:
            self.rows.add_facets(self.layout, delta.facet.parameter, delta.all_pairs(self.store))
        self.rows.set_state(self.name, self.fingerprint, through)
        logger.info("report %s built: %d keys", self.name, len(rows))

    def clear(self, through: int) -> None:
        self.rows.clear(self.layout)
        self.rows.set_state(self.name, self.fingerprint, through)

    def forget_erased(self) -> None:
        """Called by the keeper between clearing every view and building them again after an erasure."""
        self.rows.forget_erased()

    def update(self, delta: Delta, through: int) -> None:
        self._update(delta, through, record=True, between=None)

    def update_ahead(self, delta: Delta, through: int) -> None:
        self._update(delta, through, record=False, between=None)

    def update_in_parts(self, delta: Delta, through: int, between: Callable[[], int]) -> None:
        self._update(delta, through, record=True, between=between)

    def _update(self, delta: Delta, through: int, *, record: bool, between: Callable[[], int] | None) -> None:
        """The rows of the keys `delta` touches read again; `record`: the view now includes the journal through
        `through` (not for a batch taken ahead of an earlier one); `between`: the keys written a part at a time
        (each part its own transaction), calling it before each part and after the last; it answers the last
        entry taken ahead meanwhile, which the view then includes too."""
        # The store is asked everything first, then the rows change in one transaction: the reports of a remote
        # store are updated side by side, and take turns only for writing.
        replaced: list[str] = []
        rows: dict[str, list[Row]] = {}
        facets: list[tuple[FacetFilter, list[tuple[str, str]]]] = []
        if delta:
            # A key the batch introduced whose rows would need a triple the batch lacks had none before it (no
            # triple named it) and has none now: nothing to evaluate, replace or announce.
            units = self._needed.possible(delta, self.keys.units(delta, self.store))
            replaced = sorted(unit for unit in units if self._may_have_rows(delta, unit))
            if between is not None and len(replaced) > VALUES_PER_QUERY:
                self._replace_in_parts(replaced, through, between)
                replaced = []
            else:
                rows = self._evaluate(replaced) if replaced else {}
            facets = [(pairs.facet, new) for pairs in self.facets if (new := pairs.new_pairs(delta, self.store))]
        with self.rows.db.writing():
            if replaced:
                self.rows.replace(self.layout, replaced, rows, through)
            for facet, pairs in facets:
                self.rows.add_facets(self.layout, facet.parameter, pairs)
            if delta:
                self.rows.prune_changes(CHANGES_KEPT)
            if record:
                self.rows.set_state(self.name, self.fingerprint, through)
        if replaced:
            self.rows.changed.notify()
        # Batches go ahead only once this one's rows are written: rows read before a later batch's triples were
        # applied must not be written over that batch's.
        ahead = between() if between is not None else through
        if ahead > through:
            with self.rows.db.writing():
                self.rows.set_state(self.name, self.fingerprint, ahead)

    def _replace_in_parts(self, units: list[str], through: int, between: Callable[[], int]) -> None:
        for start in range(0, len(units), VALUES_PER_QUERY):
            between()
            part = units[start : start + VALUES_PER_QUERY]
            rows = self._evaluate(part)
            with self.rows.db.writing():
                self.rows.replace(self.layout, part, rows, through)
            self.rows.changed.notify()

    def _may_have_rows(self, delta: Delta, unit: str) -> bool:
        """False for a key the batch introduced (it had no row before) that the batch's triples show can have
        none: what every row needs cannot match, or what no row may have does."""
        if self._needed.run(delta, [unit]) == []:
            return False
        return not any(join.run(delta, [unit]) for join in self._excluded)  # None (not told here) or [] (none)

    # --- queries -------------------------------------------------------------------------------------

    def _evaluate(self, units: list[str] | None) -> dict[str, list[Row]]:
        """The report's rows grouped by unit: for `units` only, or (None) for all."""
        chunks: list[list[str] | None] = [None] if units is None else _slices(units, VALUES_PER_QUERY)
        grouped: dict[str, list[Row]] = {unit: [] for unit in units or []}
        for chunk in chunks:
            bound = (
                self.text
                if chunk is None
                else bind_texts(self.text, [self.unit], [[unit] for unit in chunk], wrap=self.store.wraps_values)
            )
            for row in select(self.store, bound).rows:
                unit = row.get(self.unit)
                if unit is not None:
                    grouped.setdefault(term_text(unit), []).append(row)
        return grouped


def _slices(items: list[str], size: int) -> list[list[str] | None]:
    return [items[start : start + size] for start in range(0, len(items), size)]


def kept_text(query: CatalogQuery, plan: ReportPlan) -> str:
    """The query whose answer a report's rows are, its parameters left unbound: for an aggregate, its rows before
    grouping."""
    text = query.text
    if plan.is_aggregate:
        inputs = dict.fromkeys([*plan.group_by, f"?{plan.unit()}", *(a.argument for a in plan.aggregates)])
        text = _before_grouping(text, list(inputs))
    return bind_values(text, {PARAMETER_VARIABLE_PREFIX + name: None for name in query.parameters})


def _projection(query: CatalogQuery, plan: ReportPlan, store: Store, rows: KeptRows) -> KeptQuery:
    unit = plan.unit()
    text = kept_text(query, plan)
    facet_tables = {facet.parameter: facet_table(plan, facet) for facet in plan.facet_filters}
    table = f"report_{re.sub(r'[^a-z0-9]', '_', query.name.lower())}"
    layout = Layout(table, plan, query.parameters, unit, facet_tables)
    # The tables' schema counts too: rows stored in another layout are built again, not read.
    fingerprint = hashlib.sha256("\n".join([PLAN_VERSION, query.text, *layout.schema()]).encode()).hexdigest()
    return KeptQuery(layout, unit, text, fingerprint, store, rows)


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
