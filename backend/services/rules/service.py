"""Findings: what the rules find in the log, listed across rules in time order, filtered and paged.

Each rule is a source of rows in time order: a SPARQL rule's kept rows (its own table of `findings.sqlite3`,
kept by `KeptQueries` as a report's are), or, while those are built or for a rule they cannot follow, its query
evaluated in full; a SHACL rule's rows in the shape findings' table. A page takes the next rows of every
source and merges them; its cursor (`after=`) holds each source's own position, so paging stays constant-time
per source however deep it goes and stays right while robots write.
"""

from __future__ import annotations

import base64
import heapq
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from pyoxigraph import NamedNode

from segb_server.backend.services.errors import Conflict, InvalidParameter
from segb_server.backend.services.rules.catalog import FOLDER, SEVERITIES, Rule, RuleCatalog
from segb_server.backend.services.rules.findings import Finding, finding, order_key
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, Parameter, check_window, to_term
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.services.views.kept_queries.encoding import instant, numeric_value
from segb_server.backend.services.views.kept_queries.projection import KeptQueries
from segb_server.backend.services.views.shape_checks import check_shapes
from segb_server.backend.services.views.shape_view import ShapeFindings
from segb_server.backend.services.views.signal import ChangeSignal
from segb_server.backend.store.base import Store, Term, select
from segb_server.backend.store.terms import bind_values, term_text

DEFAULT_LIMIT = 100
MAX_LIMIT = 1000
FILTERS = ("robot", "human", "since", "until")  # what every rule may declare, and the findings page filters by
SHAPE_FILTERS = ("robot", "since", "until")  # a shape's findings have a robot and a time from their focus node
_FILTER_TYPES = {"robot": "iri", "human": "iri", "since": "dateTime", "until": "dateTime"}


@dataclass(frozen=True)
class Selection:
    """What a request asks for: which rules (by id and severity), and the filters they share."""

    rules: list[Rule]
    filters: dict[str, str]

    def takes(self, rule: Rule) -> bool:
        """Whether `rule` can say anything under these filters: it declares every one given."""
        declared = SHAPE_FILTERS if rule.kind == "shacl" else tuple(rule.parameters)
        return all(name in declared for name in self.filters)


@dataclass
class FindingsPage:
    findings: list[Finding]
    has_more: bool
    next: str | None
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    served_from: dict[str, str] = field(default_factory=dict)  # rule → "rows", "query" or "building"
    last_event_id: str = "0.0"


class FindingsService:
    def __init__(
        self,
        catalog: RuleCatalog,
        store: Store,
        kept: KeptQueries | None,
        shapes: ShapeFindings | None,
        shape_rules: dict[str, ShapeRule],
    ) -> None:
        self.catalog = catalog
        self.store = store
        self.kept = kept
        self.shapes = shapes
        self.shape_rules = shape_rules
        self._quiet = ChangeSignal()  # nothing is kept: nothing changes by itself

    # --- what is asked -------------------------------------------------------------------------------

    def selection(self, values: Mapping[str, list[str]]) -> Selection:
        """The rules and filters of a query string (`rule` and `severity` may repeat); 422 naming a bad one."""
        unknown = sorted(set(values) - {"rule", "severity", *FILTERS})
        if unknown:
            raise InvalidParameter(
                unknown[0], f"not a filter of the findings ({', '.join(['rule', 'severity', *FILTERS])})"
            )
        wanted = [self.catalog.get(rule_id).id for rule_id in values.get("rule", []) if rule_id]
        severities = [s for s in values.get("severity", []) if s]
        for severity in severities:
            if severity not in SEVERITIES:
                raise InvalidParameter("severity", f"'{severity}' is not one of {', '.join(SEVERITIES)}")
        filters: dict[str, str] = {}
        for name in FILTERS:
            given = [value for value in values.get(name, []) if value]
            if len(given) > 1:
                raise InvalidParameter(name, "given more than once")
            if given:
                to_term(Parameter(name, _FILTER_TYPES[name]), given[0])  # type: ignore[arg-type]  # 422 when bad
                filters[name] = given[0]
        check_window(filters.get("since"), filters.get("until"))
        rules = [rule for rule in self.catalog
                 if (not wanted or rule.id in wanted) and (not severities or rule.severity in severities)]  # fmt: skip
        return Selection(rules, filters)

    # --- pages ---------------------------------------------------------------------------------------

    def page(self, selection: Selection, limit: int, after: str | None) -> FindingsPage:
        """The findings of the selected rules after `after`, in time order. Blocking (SQLite, the store)."""
        positions = _positions(after)
        last_event_id = self.last_event_id()  # read before the rows: a later change is announced again, not missed
        sources = [rule for rule in selection.rules if selection.takes(rule)]
        fetched: dict[str, tuple[list[dict[str, JsonValue]], bool, str]] = {}
        served: dict[str, str] = {}
        for rule in sources:
            position = positions.get(rule.id, ["o", 0])
            if position == ["done"]:
                continue
            rows, has_more, served[rule.id] = self._read(rule, selection.filters, position, limit)
            fetched[rule.id] = (rows, has_more, served[rule.id])
        merged = heapq.merge(
            *[
                [(order_key(row), rule_id, index, row) for index, row in enumerate(rows)]
                for rule_id, (rows, _, _) in fetched.items()
            ]
        )
        chosen = [entry for _, entry in zip(range(limit), merged, strict=False)]
        taken: dict[str, int] = {}
        for _, rule_id, _, _ in chosen:
            taken[rule_id] = taken.get(rule_id, 0) + 1
        has_more = any(taken.get(r, 0) < len(rows) or more for r, (rows, more, _) in fetched.items())
        next_positions = dict(positions)
        for rule_id in fetched:
            count = taken.get(rule_id, 0)
            if count:
                rule, position = self.catalog.get(rule_id), positions.get(rule_id, ["o", 0])
                next_positions[rule_id] = self._advance(rule, selection.filters, position, count, served[rule_id])
        findings = [finding(self.catalog.get(rule_id), row) for _, rule_id, _, row in chosen]
        return FindingsPage(
            findings,
            has_more,
            _cursor(next_positions) if has_more else None,
            self.counts(selection),
            served,
            last_event_id,
        )

    def _read(
        self, rule: Rule, filters: dict[str, str], position: list[Any], limit: int
    ) -> tuple[list[dict[str, JsonValue]], bool, str]:
        """`limit` rows of one rule from `position`, whether more follow, and where they came from."""
        after = position[1] if position[0] == "a" else None
        if rule.query is None and self.shapes is not None and (after is not None or position == ["o", 0]):
            # Until the shapes are first checked (minutes at a million triples: every target of every shape),
            # their findings are those checked so far, and the answer says so: a full check per request is out.
            shaped = self.shapes.page(rule.id, filters.get("robot"), *self._times(filters), limit, after)
            return shaped.rows, shaped.has_more, "rows" if self.shapes.ready else "building"
        if rule.query is not None and self.kept is not None and (after is not None or position == ["o", 0]):
            kept = self.kept.page(rule.query.name, self._bound(rule, filters), limit, 0, after)
            if kept is not None:
                return kept.rows, kept.has_more, "rows"
            if self._building(rule):
                # Not evaluated in full meanwhile, as a report is: a page reads every rule, and eleven full
                # evaluations a request at a million triples never finish. The answer says so instead.
                return [], False, "building"
        if position[0] == "a":
            raise Conflict(f"Rule '{rule.id}' is being rebuilt; start again from the first page (without `after`).")
        rows = self.evaluate_rule(rule, filters)
        window = rows[position[1] : position[1] + limit + 1]
        return window[:limit], len(window) > limit, "query"

    def _advance(self, rule: Rule, filters: dict[str, str], position: list[Any], count: int, served: str) -> list[Any]:
        """The position after `count` more rows of one rule, read as they were (`served`: "rows" or "query")."""
        if served == "query":
            return ["o", position[1] + count]
        after = position[1] if position[0] == "a" else None
        if rule.query is None:
            assert self.shapes is not None
            next_after = self.shapes.page(rule.id, filters.get("robot"), *self._times(filters), count, after).after
        else:
            assert self.kept is not None
            kept = self.kept.page(rule.query.name, self._bound(rule, filters), count, 0, after)
            if kept is None:
                raise Conflict(f"Rule '{rule.id}' is being rebuilt; start again from the first page (without `after`).")
            next_after = kept.after
        return ["a", next_after] if next_after else ["done"]

    def about(self, iris: list[str]) -> list[Finding]:
        """Every finding whose focus is one of `iris` (the explain page marks what they are about), in time order:
        read by key from the kept rows, or from each rule evaluated in full while those are not there."""
        units = sorted({term_text(NamedNode(iri)) for iri in iris})
        found: list[tuple[tuple[object, ...], str, dict[str, JsonValue]]] = []
        for rule in self.catalog:
            if rule.query is None and self.shapes is not None:
                rows = self.shapes.unit_rows(rule.id, units)
            elif rule.query is not None and self.kept is not None and (kept := self.kept.reports.get(rule.query.name)) \
                    and kept.ready:  # fmt: skip
                bound, compared = self._bound(rule, {}), kept.layout.plan.column_filters
                rows = [row for row in self.kept.rows.rows_of(kept.layout, iris) if _passes(row, compared, bound)]
            elif self._building(rule):
                rows = []
            else:
                rows = [row for row in self.evaluate_rule(rule, {}) if row.get("focus") in iris]
            found += [(order_key(row), rule.id, row) for row in rows]
        found.sort(key=lambda entry: (entry[0], entry[1]))
        return [finding(self.catalog.get(rule_id), row) for _, rule_id, row in found]

    # --- counts --------------------------------------------------------------------------------------

    def counts(self, selection: Selection) -> dict[str, dict[str, int]]:
        """Findings per rule and per severity under the selection's filters (every rule, whichever are listed)."""
        by_rule: dict[str, int] = {}
        for rule in self.catalog:
            by_rule[rule.id] = self.count(rule, selection.filters) if selection.takes(rule) else 0
        by_severity: dict[str, int] = {severity: 0 for severity in SEVERITIES}
        for rule in self.catalog:
            by_severity[rule.severity] += by_rule[rule.id]
        return {"by_rule": by_rule, "by_severity": by_severity}

    def _building(self, rule: Rule) -> bool:
        """A SPARQL rule whose rows are kept but not built yet."""
        kept = self.kept.reports.get(rule.query.name) if self.kept is not None and rule.query is not None else None
        return kept is not None and not kept.ready

    def count(self, rule: Rule, filters: dict[str, str]) -> int:
        if rule.query is None and self.shapes is not None:
            return self.shapes.count(rule.id, filters.get("robot"), *self._times(filters))
        if self.kept is not None and rule.query is not None:
            projection = self.kept.reports.get(rule.query.name)
            if projection is not None and projection.ready:
                return self.kept.rows.count(projection.layout, self._bound(rule, filters))
            if projection is not None:
                return 0  # being built (see `_read`)
        return len(self.evaluate_rule(rule, filters))

    @property
    def changed(self) -> ChangeSignal:
        """Wakes live readers when findings change (the kept rows and the shape findings share it)."""
        if self.kept is not None:
            return self.kept.rows.changed
        return self.shapes.changed if self.shapes is not None else self._quiet

    def changed_rules(self, seen: str) -> tuple[str, list[str]]:
        """Where the findings' changes stand now, and the rules whose findings changed since `seen` (a former
        position; any other text: none named)."""
        current = self.last_event_id()
        if current == seen:
            return current, []
        rows_seen, _, shapes_seen = seen.partition(".")
        if not (rows_seen.isdigit() and shapes_seen.isdigit()):
            return current, []
        changed: set[str] = set()
        if self.kept is not None:
            changed.update(
                name.removeprefix(f"{FOLDER}/") for _, name, _ in self.kept.rows.changes_since(int(rows_seen))
            )
        if self.shapes is not None:
            changed.update(rule for _, rule, _ in self.shapes.changes_since(int(shapes_seen)))
        return current, sorted(changed)

    def last_event_id(self) -> str:
        """Where the findings' changes stand: the kept rows' last change and the shape findings' ('a.b')."""
        rows = self.kept.rows.last_change() if self.kept is not None else 0
        shapes = self.shapes.last_change() if self.shapes is not None else 0
        return f"{rows}.{shapes}"

    # --- full evaluation -----------------------------------------------------------------------------

    def evaluate_rule(self, rule: Rule, filters: dict[str, str]) -> list[dict[str, JsonValue]]:
        """A rule's rows evaluated in full (a SPARQL rule's query; a SHACL rule on every target), in time order."""
        if rule.query is None:
            return self._evaluate_shapes(rule, filters)
        bindings = rule.query.bindings({name: value for name, value in filters.items() if name in rule.parameters})
        result = select(self.store, bind_values(rule.query.text, bindings))
        rows = [{column: json_value(row.get(column)) for column in result.columns} for row in result.rows]
        return sorted(rows, key=order_key)

    def _evaluate_shapes(self, rule: Rule, filters: dict[str, str]) -> list[dict[str, JsonValue]]:
        _, found = check_shapes(self.shape_rules[rule.id], self.store, None)
        since, until = (instant(term) if term is not None else None for term in self._times(filters))
        rows = [
            row
            for records in found.values()
            for _, moment, robot, row in records
            if (filters.get("robot") is None or robot == filters["robot"])
            and (since is None or (moment is not None and moment >= since))
            and (until is None or (moment is not None and moment <= until))
        ]
        return sorted(rows, key=order_key)

    def _bound(self, rule: Rule, filters: dict[str, str]) -> dict[str, Term | None]:
        assert rule.query is not None
        bindings = rule.query.bindings({name: value for name, value in filters.items() if name in rule.parameters})
        return {name: bindings[PARAMETER_VARIABLE_PREFIX + name] for name in rule.parameters}

    @staticmethod
    def _times(filters: dict[str, str]) -> tuple[Term | None, Term | None]:
        return tuple(  # type: ignore[return-value]
            to_term(Parameter(name, "dateTime"), filters[name]) if name in filters else None
            for name in ("since", "until")
        )


def _passes(row: dict[str, JsonValue], comparisons: list[Any], bound: dict[str, Term | None]) -> bool:
    """Whether a kept row passes the rule's own parameters at their defaults (a threshold, a delay): rows are kept
    for every value and a page compares them on their columns; a row read by key is compared here the same way
    (the query's `FILTER (!BOUND(?param_x) || ?column >= ?param_x)`, as its plan read it)."""
    for comparison in comparisons:
        term = bound.get(comparison.parameter)
        if term is None or comparison.parameter in FILTERS:
            continue
        value, limit = row.get(comparison.column[1:]), numeric_value(term)
        if limit is None or not isinstance(value, int | float):
            return False
        if not {"=": value == limit, ">=": value >= limit, "<=": value <= limit}[comparison.op]:
            return False
    return True


def _positions(after: str | None) -> dict[str, list[Any]]:
    """Each rule's position in a `next` cursor; 422 for anything this server did not make."""
    if after is None:
        return {}
    try:
        decoded = json.loads(base64.urlsafe_b64decode(after.encode("ascii") + b"=" * (-len(after) % 4)))
    except (ValueError, UnicodeError):
        decoded = None
    valid = isinstance(decoded, dict) and all(
        isinstance(key, str) and isinstance(value, list) and value and value[0] in ("a", "o", "done")
        for key, value in decoded.items()
    )
    if not valid or any(value[0] == "o" and not (len(value) == 2 and isinstance(value[1], int) and value[1] >= 0)
                        for value in decoded.values()):  # fmt: skip
        raise InvalidParameter("after", "not a cursor this server made: pass the `next` of the previous page")
    return decoded


def _cursor(positions: dict[str, list[Any]]) -> str:
    return base64.urlsafe_b64encode(json.dumps(positions, sort_keys=True).encode()).decode("ascii").rstrip("=")
