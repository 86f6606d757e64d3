"""Keeping materialised reports current from what each applied journal step added.

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
import queue
import re
import threading
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from pyoxigraph import Quad, RdfFormat, Triple, parse

from segb_server.backend.services.ingest.applier import Applied
from segb_server.backend.services.ingest.journal import Journal
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.views.materialized.plan import (
    FacetFilter,
    Pattern,
    ReportPlan,
    Unsupported,
    plan_report,
)
from segb_server.backend.services.views.materialized.rows import Layout, Page, ReportRows, Row
from segb_server.backend.store.base import Store, StoreError, Term, select
from segb_server.backend.store.sparql_text import code_only
from segb_server.backend.store.terms import bind_rows, bind_values, term_text

logger = logging.getLogger("segb.reports")

PLAN_VERSION = "1"  # bump when the stored layout changes: every report is then built again
VALUES_PER_QUERY = 300
CHANGES_KEPT = 20_000


@dataclass
class Materialized:
    """One report kept as rows: its layout, the variable its rows are replaced by, and its queries."""

    layout: Layout
    unit: str  # variable name (no ?) whose values the rows are replaced by
    text: str  # the query whose answer the rows are (for an aggregate: before grouping)
    fingerprint: str
    ready: bool = False


class ReportMaintainer:
    def __init__(self, store: Store, journal: Journal, rows: ReportRows) -> None:
        self.store = store
        self.journal = journal
        self.rows = rows
        self.reports: dict[str, Materialized] = {}
        self.unsupported: dict[str, str] = {}
        self._queue: queue.Queue[Applied | _Marker | None] = queue.Queue()
        self._thread: threading.Thread | None = None
        self._stopping = (
            threading.Event()
        )  # ends the retry waits too: a store that never returns must not hold shutdown
        self.last_error: str | None = None
        self.through = 0  # the journal entry the rows are current through

    def add(self, query: CatalogQuery) -> None:
        """Keep `query` current (or note why it cannot be, once, at start-up)."""
        try:
            plan = plan_report(query)
            materialized = _materialized(query, plan)
        except Unsupported as reason:
            self.unsupported[query.name] = str(reason)
            logger.warning("report %s is evaluated in full on every request: %s", query.name, reason)
            return
        self.reports[query.name] = materialized

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="segb-reports", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stopping.set()
        self._queue.put(None)
        if self._thread is not None:
            self._thread.join(timeout=30)

    def on_applied(self, step: Applied) -> None:
        self._queue.put(step)

    def page(self, name: str, bound: dict[str, Term | None], limit: int, offset: int, after: str | None) -> Page | None:
        """A page served from the rows, or None while the report is not (or cannot be) materialised."""
        materialized = self.reports.get(name)
        if materialized is None or not materialized.ready:
            return None
        return self.rows.page(materialized.layout, bound, limit, offset, after)

    def wait_until_current(self, timeout: float) -> bool:
        """Wait until every step applied so far is in the rows (for tests and the benchmark)."""
        done = threading.Event()
        self._queue.put(_Marker(done))
        return done.wait(timeout)

    # --- the thread ----------------------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            try:
                self._build_all()
                break
            except StoreError as error:
                self.last_error = str(error)
                logger.warning("building reports failed (%s); retrying", error)
                if self._stopping.wait(2):
                    return
        while True:
            steps: list[Applied | _Marker | None] = [self._queue.get()]
            while not self._queue.empty() and len(steps) < 200:
                steps.append(self._queue.get())
            if any(step is None for step in steps):
                return
            markers = [step for step in steps if isinstance(step, _Marker)]
            applied = [step for step in steps if isinstance(step, Applied)]
            while True:
                try:
                    if applied:
                        self._process(applied)
                    self.last_error = None
                    break
                except StoreError as error:
                    self.last_error = str(error)
                    logger.warning("keeping reports current failed (%s); retrying", error)
                    if self._stopping.wait(1):
                        return
                except Exception:
                    logger.exception("keeping reports current failed; building them again")
                    for materialized in self.reports.values():
                        self._build(materialized)
                    break
            if applied:
                self.through = max(self.through, applied[-1].entries[-1].sequence)
            for marker in markers:
                marker.done.set()

    def _build_all(self) -> None:
        started_through = self.store.applied_through() or 0
        for name, materialized in self.reports.items():
            fingerprint, through = self.rows.state(name)
            if fingerprint == materialized.fingerprint:
                self._catch_up(materialized, through)
            else:
                self._build(materialized)
            materialized.ready = True
        self.through = max(self.through, started_through)
        self.rows.prune_changes(CHANGES_KEPT)

    def lag(self, applied: int) -> int:
        """Journal entries the store has and the rows do not have yet. While the rows are first built, reports
        are answered by evaluating their queries, which see everything: no lag then."""
        if not any(materialized.ready for materialized in self.reports.values()):
            return 0
        return max(0, applied - self.through)

    def _build(self, materialized: Materialized) -> None:
        started = time.perf_counter()
        through = self.store.applied_through() or 0
        self.rows.create(materialized.layout, fresh=True)
        rows = self._evaluate(materialized, None)
        self.rows.replace(materialized.layout, rows, rows, through)
        self.rows.set_state(materialized.layout.plan.name, materialized.fingerprint, through)
        logger.info(
            "report %s built: %d keys in %.1f s",
            materialized.layout.plan.name,
            len(rows),
            time.perf_counter() - started,
        )

    def _catch_up(self, materialized: Materialized, through: int) -> None:
        """Apply to the rows what the store received while this server was not keeping them current."""
        self.rows.create(materialized.layout, fresh=False)
        current = self.store.applied_through() or 0
        if current == through:
            return
        entries = self.journal.entries_after(through, current - through)
        if any(entry.action == "delete_all" for entry in entries):
            self._build(materialized)
            return
        quads = [quad for entry in entries if entry.content for quad in parse(entry.content, RdfFormat.N_TRIPLES)]
        self._update(materialized, quads, current)

    def _process(self, steps: list[Applied]) -> None:
        through = steps[-1].entries[-1].sequence
        cleared = max((index for index, step in enumerate(steps) if step.cleared), default=-1)
        if cleared >= 0:
            for materialized in self.reports.values():
                self.rows.clear(materialized.layout)
            steps = steps[cleared + 1 :]
        quads = [quad for step in steps for quad in step.quads]
        for materialized in self.reports.values():
            self._update(materialized, quads, through)

    def _update(self, materialized: Materialized, quads: list[Quad], through: int) -> None:
        plan = materialized.layout.plan
        if quads:
            units = units_touched(plan, materialized.unit, quads, self.store)
            if units:
                rows = self._evaluate(materialized, sorted(units))
                self.rows.replace(materialized.layout, sorted(units), rows, through)
            for facet in plan.facet_filters:
                anchors = units_touched(_facet_plan(plan, facet), facet.anchor[1:], quads, self.store)
                if anchors:
                    self._update_facet(materialized, facet, sorted(anchors))
        self.rows.set_state(plan.name, materialized.fingerprint, through)

    # --- queries -------------------------------------------------------------------------------------

    def _evaluate(self, materialized: Materialized, units: list[str] | None) -> dict[str, list[Row]]:
        """The report's rows grouped by unit: for `units` only, or (None) for all."""
        unbound = {PARAMETER_VARIABLE_PREFIX + p: None for p in materialized.layout.parameters}
        text = bind_values(materialized.text, unbound)
        chunks = [None] if units is None else [units[i : i + VALUES_PER_QUERY] for i in range(0, len(units), 300)]
        grouped: dict[str, list[Row]] = {unit: [] for unit in units or []}
        for chunk in chunks:
            bound = text if chunk is None else bind_rows(text, [materialized.unit], [[_term(unit)] for unit in chunk])
            for row in select(self.store, bound).rows:
                unit = row.get(materialized.unit)
                if unit is not None:
                    grouped.setdefault(term_text(unit), []).append(row)
        return grouped

    def _update_facet(self, materialized: Materialized, facet: FacetFilter, anchors: list[str]) -> None:
        variable = PARAMETER_VARIABLE_PREFIX + facet.parameter
        branches = " UNION ".join("{ " + " ".join(p.sparql() for p in body) + " }" for body in facet.bodies)
        pairs: list[tuple[str, str]] = []
        for start in range(0, len(anchors), VALUES_PER_QUERY):
            chunk = anchors[start : start + VALUES_PER_QUERY]
            values = " ".join(chunk)
            selected = f"SELECT DISTINCT {facet.anchor} ?{variable}"
            query = f"{selected} WHERE {{ VALUES {facet.anchor} {{ {values} }} {branches} }}"
            for row in select(self.store, query).rows:
                anchor, value = row.get(facet.anchor[1:]), row.get(variable)
                if anchor is not None and value is not None:
                    pairs.append((term_text(anchor), term_text(value)))
        self.rows.replace_facets(materialized.layout, facet.parameter, anchors, pairs)


@dataclass
class _Marker:
    done: threading.Event


def units_touched(plan: ReportPlan, unit: str, quads: list[Quad], store: Store) -> set[str]:
    """The units (values of `?unit`, as N-Triples text) whose rows the new `quads` may change."""
    target = f"?{unit}"
    units: set[str] = set()
    by_predicate: dict[str, list[Quad]] = {}
    for quad in quads:
        by_predicate.setdefault(quad.predicate.value, []).append(quad)
    for pattern in plan.patterns:
        matches = [q for p in pattern.predicates for q in by_predicate.get(p, []) if _fits(pattern, q)]
        if not matches:
            continue
        bindings = [_bind(pattern, q) for q in matches]
        if target in pattern.variables():
            units.update(term_text(binding[target]) for binding in bindings if target in binding)
            continue
        names = sorted(pattern.variables())
        rows = list({tuple(term_text(binding[name]) for name in names): binding for binding in bindings}.values())
        bodies = " UNION ".join("{ " + " ".join(path) + " }" for path in paths(plan, pattern, target))
        for start in range(0, len(rows), VALUES_PER_QUERY):
            chunk = rows[start : start + VALUES_PER_QUERY]
            values = " ".join("(" + " ".join(term_text(binding[name]) for name in names) + ")" for binding in chunk)
            query = f"SELECT DISTINCT {target} WHERE {{ VALUES ({' '.join(names)}) {{ {values} }} {bodies} }}"
            units.update(term_text(row[unit]) for row in select(store, query).rows if unit in row)
    return units


def _fits(pattern: Pattern, quad: Quad) -> bool:
    """A triple fits a pattern when its terms equal the pattern's constants."""
    for position, term in ((pattern.subject, quad.subject), (pattern.object, quad.object)):
        if not position.startswith("?") and position != term_text(term):
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
    found = _shortest(start, base, plan.aliases, target)
    if found is not None:
        return [found]
    chains = [
        chain
        for branch in plan.branch_choices(start)
        if (chain := _shortest(start, base + branch, plan.aliases, target))
    ]
    if not chains:
        raise Unsupported(f"no path from {start.sparql()} to {target}")
    return chains


def _shortest(start: Pattern, usable: list[Pattern], aliases: list[tuple[str, str]], target: str) -> list[str] | None:
    """Breadth first over variables: a pattern joins its variables; an alias binds one from the other."""
    frontier: deque[tuple[str, list[str]]] = deque((variable, []) for variable in start.variables())
    seen = set(start.variables())
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


def _facet_plan(plan: ReportPlan, facet: FacetFilter) -> ReportPlan:
    """A plan whose patterns are a facet's EXISTS bodies, to find the anchors new triples touch."""
    patterns = [pattern for body in facet.bodies for pattern in body]
    groups = {pattern.group for pattern in patterns}
    return ReportPlan(
        name=plan.name,
        key=(facet.anchor,),
        columns=[facet.anchor],
        order=[],
        patterns=patterns,
        guaranteed={group: {group} for group in groups},
        mandatory={group: [p for p in patterns if p.group == group] for group in groups},
    )


def _term(text: str) -> Term:
    """The term whose N-Triples text is `text` (how units are stored)."""
    term = next(iter(parse(f"<urn:x:s> <urn:x:p> {text} .".encode(), RdfFormat.N_TRIPLES))).object
    assert not isinstance(term, Triple)
    return term


def _materialized(query: CatalogQuery, plan: ReportPlan) -> Materialized:
    if plan.is_aggregate:
        counted = [a for a in plan.aggregates if a.function == "count" and a.distinct]
        if len(counted) != 1:
            raise Unsupported("an aggregate report needs one COUNT(DISTINCT ?x) to keep its contributions by")
        unit = counted[0].argument[1:]
        inputs = dict.fromkeys([*plan.group_by, counted[0].argument, *(a.argument for a in plan.aggregates)])
        text = _before_grouping(query.text, list(inputs))
        _check_reachable(plan, counted[0].argument)
    else:
        if len(plan.key) != 1:
            raise Unsupported("a report's key is one variable")
        unit = plan.key[0][1:]
        text = query.text
        _check_reachable(plan, plan.key[0])
    layout = Layout(f"report_{re.sub(r'[^a-z0-9]', '_', query.name.lower())}", plan, query.parameters)
    fingerprint = hashlib.sha256(f"{PLAN_VERSION}\n{query.text}".encode()).hexdigest()
    return Materialized(layout, unit, text, fingerprint)


def _check_reachable(plan: ReportPlan, target: str) -> None:
    """Every pattern must lead to the unit variable, or new triples it matches could not be traced to rows."""
    for pattern in plan.patterns:
        if target not in pattern.variables():
            paths(plan, pattern, target)


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
