"""What keeping a report current needs, read from its `.rq` file: the triple patterns and which of them are
sure to hold together, the filters its parameters switch on, its sort order, and (for an aggregate) its
groups. Only the row key is declared in the file's header (`# key: ?message`); everything else is derived
from the query itself, so a report stays defined by its `.rq` file alone.

A construct this plan cannot follow makes the report `Unsupported`: it is then served by evaluating the
query in full, never from rows that might be wrong.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

from rdflib.paths import AlternativePath, InvPath, MulPath, Path, SequencePath
from rdflib.plugins.sparql.parserutils import CompValue
from rdflib.term import BNode, Identifier, URIRef, Variable

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.sparql.parser import exists_groups, translate_query

_KEY = re.compile(r"#\s*key:\s*((?:\?\w+\s*)+)")
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
    walker = _Walker(exists_groups(query.text))
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


class _Walker:
    """Walks rdflib's algebra of a query, collecting patterns per scope group."""

    def __init__(self, written: list[CompValue]) -> None:
        # The EXISTS groups as written, by their triples (`_graph`)
        self._written = {_triples_of(graph): graph for graph in written}
        self.patterns: list[Pattern] = []
        self.mandatory: dict[int, list[Pattern]] = {}
        self.parent: dict[int, int | None] = {}
        self.column_filters: list[ColumnFilter] = []
        self.exists_filters: dict[str, list[tuple[Pattern, ...]]] = {}
        self.order: list[str] = []
        self.aggregates: list[Aggregate] = []
        self.group_by: list[str] = []
        self._renamed: dict[str, str] = {}  # __agg_1__ → humanName
        self.branches: dict[int, int] = {}
        self.aliases: list[tuple[str, str]] = []
        self.narrowed: dict[tuple[int, str], frozenset[str]] = {}
        self.projections = 0  # more than one: a sub-select
        self._fresh = itertools.count()
        self._negated: list[int] = []  # the groups of the top group's NOT EXISTS bodies
        self._bound_elsewhere: set[str] = set()  # variables a BIND or VALUES binds (patterns' are in `patterns`)

    def new_group(self, parent: int | None) -> int:
        group = len(self.parent)
        self.parent[group] = parent
        self.mandatory[group] = []
        return group

    def guaranteed(self) -> dict[int, set[int]]:
        found: dict[int, set[int]] = {}
        for group in self.parent:
            chain: set[int] = set()
            current: int | None = group
            while current is not None:
                chain.add(current)
                current = self.parent[current]
            found[group] = chain
        return found

    def exclusions(self) -> list[Exclusion]:
        """The top group's NOT EXISTS bodies of triple patterns alone (no nested filter), with what they share."""
        found = []
        for body in self._negated:
            if any(parent == body for parent in self.parent.values()):
                continue  # a nested EXISTS: its patterns are not all the body needs
            inside = {variable for pattern in self.mandatory[body] for variable in pattern.variables()}
            outside = self._bound_elsewhere.union(
                *(pattern.variables() for pattern in self.patterns if pattern.group != body)
            )
            if self.mandatory[body]:
                found.append(Exclusion(list(self.mandatory[body]), frozenset(inside & outside)))
        return found

    def facets(self, columns: list[str]) -> list[FacetFilter]:
        facets = []
        for parameter, bodies in self.exists_filters.items():
            variables = set().union(*(pattern.variables() for body in bodies for pattern in body))
            anchors = sorted(variables & set(columns))
            if len(anchors) != 1:
                raise Unsupported(f"the EXISTS filter of {parameter} must mention exactly one column")
            facets.append(FacetFilter(parameter, anchors[0], tuple(tuple(body) for body in bodies)))
        return facets

    # --- the algebra ---------------------------------------------------------------------------------

    def visit(self, node: object, group: int) -> None:
        if not isinstance(node, CompValue):
            return
        name = node.name
        if name in ("SelectQuery", "Project", "Distinct", "Reduced", "Slice", "ToMultiSet"):
            self.projections += name == "Project"
            self.visit(node.get("p"), group)
        elif name == "OrderBy":
            for condition in node["expr"]:
                if dict.get(condition, "order") == "DESC" or not isinstance(condition["expr"], Variable):
                    raise Unsupported("only ascending ORDER BY of variables")
                self.order.append("?" + str(condition["expr"]))
            self.visit(node["p"], group)
        elif name == "BGP":
            for triple in node["triples"]:
                self._pattern(triple, group)
        elif name in ("Join", "Minus"):
            if name == "Minus":
                raise Unsupported("MINUS")
            self.visit(node["p1"], group)
            self.visit(node["p2"], group)
        elif name == "LeftJoin":
            self.visit(node["p1"], group)
            optional = self.new_group(group)
            self.branches[optional] = group
            self.visit(node["p2"], optional)
            self._expression(node.get("expr"), optional)
            for conjunct in _conjuncts(node.get("expr")):  # `OPTIONAL { ?x a ?c FILTER (?c IN (…)) }` narrows ?c
                if (listed := _iri_list(conjunct)) is not None:
                    self.narrowed[(optional, listed[0])] = listed[1]
        elif name == "Union":
            for side in (node["p1"], node["p2"]):
                branch = self.new_group(group)
                self.branches[branch] = group
                self.visit(side, branch)
        elif name == "Filter":
            self._filter(node["expr"], group)
            self.visit(node["p"], group)
        elif name == "Extend":
            self._expression(node["expr"], group)
            expression, bound = node["expr"], f"?{node['var']}"
            self._bound_elsewhere.add(bound)
            if isinstance(expression, Variable) and str(expression).startswith("__agg_"):
                self._renamed[str(expression)] = str(node["var"])
            elif isinstance(expression, Variable):
                self.aliases.append((bound, f"?{expression}"))
            elif isinstance(expression, CompValue) and expression.name == "Builtin_COALESCE":
                # BIND (COALESCE(?a, ?b) AS ?x): ?x is ?a or ?b, so a triple about ?x concerns their rows
                self.aliases += [(bound, f"?{arg}") for arg in expression["arg"] if isinstance(arg, Variable)]
            self.visit(node["p"], group)
        elif name == "AggregateJoin":
            self._aggregates(node["A"])
            self.visit(node["p"], group)
        elif name == "Group":
            self.group_by = ["?" + str(term) for term in node.get("expr") or [] if isinstance(term, Variable)]
            self.visit(node["p"], group)
        elif name == "ToMultiSet" or name == "values":
            self._bound_elsewhere.update(f"?{variable}" for row in node.get("res") or [] for variable in row)
        else:
            raise Unsupported(f"{name} is not supported")

    def _aggregates(self, aggregates: list[CompValue]) -> None:
        functions = {"Aggregate_Count": "count", "Aggregate_Sample": "sample", "Aggregate_Min": "min"}
        functions["Aggregate_Max"] = "max"
        for aggregate in aggregates:
            function = functions.get(aggregate.name)
            argument = aggregate.get("vars")
            if function is None or not isinstance(argument, Variable):
                raise Unsupported(f"aggregate {aggregate.name}")
            output = "?" + self._renamed.get(str(aggregate["res"]), str(aggregate["res"]))
            if output == f"?{argument}":  # a group variable, projected as itself
                continue
            distinct = dict.get(aggregate, "distinct") == "DISTINCT"
            self.aggregates.append(Aggregate(function, f"?{argument}", output, distinct))  # type: ignore[arg-type]

    def _filter(self, expression: object, group: int) -> None:
        for conjunct in _conjuncts(expression):
            if (listed := _iri_list(conjunct)) is not None:
                self.narrowed[(group, listed[0])] = listed[1]
            switched = _switched_filter(conjunct)
            if switched is None and _is_not_exists(conjunct) and self.parent[group] is None:
                body = self.new_group(group)
                self._graph(conjunct["graph"], body)  # type: ignore[index]
                # A condition in the body (`FILTER (?x != …)`) is not among its patterns, which may then match
                # where the body does not: such a body excludes nothing.
                written: CompValue = conjunct["graph"]  # type: ignore[index]
                if not _has_filter(self._written.get(_triples_of(written), written)):
                    self._negated.append(body)
                continue
            if switched is None:
                self._expression(conjunct, group)
                continue
            parameter, condition = switched
            if isinstance(condition, ColumnFilter):
                self.column_filters.append(condition)
                continue
            bodies = []
            for graph in condition:
                body = self.new_group(group)
                self._graph(graph, body)
                bodies.append(tuple(self.mandatory[body]))
            self.exists_filters[parameter] = bodies

    def _expression(self, expression: object, group: int) -> None:
        """EXISTS and NOT EXISTS inside an expression: their patterns form a group nested in `group`."""
        for graph in _exists_graphs(expression):
            self._graph(graph, self.new_group(group))

    def _graph(self, graph: CompValue, group: int) -> None:
        """A group graph pattern as the parser leaves it inside EXISTS (not translated to algebra). The group as
        written, when the translation lost part of it (a FILTER nested in an EXISTS a BIND holds): its nested
        EXISTS are patterns a new triple may change a row through."""
        graph = self._written.get(_triples_of(graph), graph)
        for part in graph.get("part") or []:
            if part.name == "TriplesBlock":
                for triples in part["triples"]:  # s p o s p o …: `;` and `,` lists come flattened
                    terms = list(triples)
                    for start in range(0, len(terms) - 2, 3):
                        self._pattern((terms[start], terms[start + 1], terms[start + 2]), group)
            elif part.name == "InlineData":
                if len(part["var"]) == 1 and all(isinstance(value, URIRef) for value in part["value"]):
                    self.narrowed[(group, f"?{part['var'][0]}")] = frozenset(value.n3() for value in part["value"])
            elif part.name == "Filter":
                self._expression(part["expr"], group)
            else:
                raise Unsupported(f"{part.name} inside EXISTS")

    def _pattern(self, triple: tuple[object, object, object], group: int) -> None:
        subject, predicate, obj = (_text(triple[0]), triple[1], _text(triple[2]))
        for step in self._expand(subject, predicate, obj):
            self.patterns.append(Pattern(step[0], step[1], step[2], group))
            self.mandatory[group].append(self.patterns[-1])

    def _expand(self, subject: str, predicate: object, obj: str) -> list[tuple[str, frozenset[str], str]]:
        if isinstance(predicate, URIRef):
            return [(subject, frozenset({str(predicate)}), obj)]
        if isinstance(predicate, AlternativePath) and all(isinstance(arg, URIRef) for arg in predicate.args):
            return [(subject, frozenset(str(arg) for arg in predicate.args), obj)]
        if isinstance(predicate, InvPath):
            return self._expand(obj, predicate.arg, subject)
        if isinstance(predicate, SequencePath):
            steps: list[tuple[str, frozenset[str], str]] = []
            current = subject
            for index, arg in enumerate(predicate.args):
                target = obj if index == len(predicate.args) - 1 else f"?_path{next(self._fresh)}"
                steps += self._expand(current, arg, target)
                current = target
            return steps
        if isinstance(predicate, MulPath | Path | Variable):
            raise Unsupported(f"the path or predicate {predicate}")
        raise Unsupported(f"the predicate {predicate!r}")


def _triples_of(graph: CompValue) -> tuple[str, ...]:
    """A group's triples as text: the same for the group as written and as the translation left it."""
    return tuple(
        str([str(term) for term in triples])
        for part in graph.get("part") or []
        if part.name == "TriplesBlock"
        for triples in part["triples"]
    )


def _text(term: object) -> str:
    if isinstance(term, Variable):
        return f"?{term}"
    if isinstance(term, BNode):
        raise Unsupported("blank nodes in patterns")
    if isinstance(term, Identifier):
        return term.n3()
    raise Unsupported(f"the term {term!r}")


def _iri_list(expression: object) -> tuple[str, frozenset[str]] | None:
    """`?x IN (<a>, <b>, …)`, all IRIs: (?x, their N-Triples texts)."""
    if not (isinstance(expression, CompValue) and expression.name == "RelationalExpression"):
        return None
    variable, others = expression.get("expr"), expression.get("other") or []
    if expression.get("op") != "IN" or not isinstance(variable, Variable) or not others:
        return None
    if not all(isinstance(other, URIRef) for other in others):
        return None
    return f"?{variable}", frozenset(other.n3() for other in others)


def _has_filter(graph: CompValue) -> bool:
    return any(part.name == "Filter" for part in graph.get("part") or [])


def _is_not_exists(expression: object) -> bool:
    return isinstance(expression, CompValue) and expression.name == "Builtin_NOTEXISTS"


def _conjuncts(expression: object) -> list[object]:
    if isinstance(expression, CompValue) and expression.name == "ConditionalAndExpression":
        return [expression["expr"], *(expression.get("other") or [])]
    return [expression]


def _switched_filter(expression: object) -> tuple[str, ColumnFilter | list[CompValue]] | None:
    """`!BOUND(?param_x) || …`: the parameter and what it filters, or None for any other filter."""
    if not (isinstance(expression, CompValue) and expression.name == "ConditionalOrExpression"):
        return None
    first = expression["expr"]
    rest = list(expression.get("other") or [])
    if not (isinstance(first, CompValue) and first.name == "UnaryNot" and first["expr"].name == "Builtin_BOUND"):
        return None
    parameter = str(first["expr"]["arg"])
    if not parameter.startswith(PARAMETER_VARIABLE_PREFIX):
        return None
    name = parameter.removeprefix(PARAMETER_VARIABLE_PREFIX)
    if len(rest) == 1 and rest[0].name == "RelationalExpression":
        relation = rest[0]
        column, op, other = relation["expr"], relation["op"], relation["other"]
        if isinstance(column, Variable) and str(other) == parameter and op in ("=", ">=", "<="):
            return name, ColumnFilter(name, f"?{column}", op)
        raise Unsupported(f"the filter of {name}")
    if rest and all(isinstance(part, CompValue) and part.name == "Builtin_EXISTS" for part in rest):
        return name, [part["graph"] for part in rest]
    raise Unsupported(f"the filter of {name}")


def _exists_graphs(expression: object) -> list[CompValue]:
    found: list[CompValue] = []
    stack = [expression]
    while stack:
        node = stack.pop()
        if isinstance(node, CompValue):
            if node.name in ("Builtin_EXISTS", "Builtin_NOTEXISTS"):
                found.append(node["graph"])
                continue
            stack.extend(value for key, value in node.items() if key != "_vars")
        elif isinstance(node, list):
            stack.extend(node)
    return found
