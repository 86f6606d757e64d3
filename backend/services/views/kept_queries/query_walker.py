"""The walk of rdflib's algebra of a report's query that collects what its plan is made of: the triple patterns
of each scope (the top group, an OPTIONAL, a UNION branch, an EXISTS body), the filters its parameters switch on,
its order, aggregates and groups, what BIND and VALUES bind and narrow."""

from __future__ import annotations

import itertools

from rdflib.paths import AlternativePath, InvPath, MulPath, Path, SequencePath
from rdflib.plugins.sparql.parserutils import CompValue
from rdflib.term import URIRef, Variable

from segb_server.backend.services.views.kept_queries.algebra_nodes import (
    conjuncts,
    exists_graphs,
    has_filter,
    iri_list,
    is_not_exists,
    pattern_term,
    switched_filter,
    triples_of,
    unwrapped,
)
from segb_server.backend.services.views.kept_queries.plan_parts import (
    Aggregate,
    ColumnFilter,
    Exclusion,
    FacetFilter,
    Pattern,
    Unsupported,
)


class QueryWalker:
    """Walks rdflib's algebra of a query, collecting patterns per scope group."""

    def __init__(self, written: list[CompValue]) -> None:
        # The EXISTS groups as written, by their triples (`_graph`)
        self._written = {triples_of(graph): graph for graph in written}
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
            for conjunct in conjuncts(node.get("expr")):  # `OPTIONAL { ?x a ?c FILTER (?c IN (…)) }` narrows ?c
                if (listed := iri_list(conjunct)) is not None:
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
        for conjunct in conjuncts(expression):
            if (listed := iri_list(conjunct)) is not None:
                self.narrowed[(group, listed[0])] = listed[1]
            switched = switched_filter(conjunct)
            if switched is None and is_not_exists(conjunct) and self.parent[group] is None:
                body = self.new_group(group)
                self._graph(conjunct["graph"], body)  # type: ignore[index]
                # A condition in the body (`FILTER (?x != …)`) is not among its patterns, which may then match
                # where the body does not: such a body excludes nothing.
                written: CompValue = conjunct["graph"]  # type: ignore[index]
                if not has_filter(self._written.get(triples_of(written), written)):
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
        for graph in exists_graphs(expression):
            self._graph(graph, self.new_group(group))

    def _graph(self, graph: CompValue, group: int) -> None:
        """A group graph pattern as the parser leaves it inside EXISTS (not translated to algebra). The group as
        written, when the translation lost part of it (a FILTER nested in an EXISTS a BIND holds): its nested
        EXISTS are patterns a new triple may change a row through."""
        graph = self._written.get(triples_of(graph), graph)
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
                # `EXISTS { ?x a ?c FILTER (?c IN (…)) }` narrows ?c
                for conjunct in conjuncts(unwrapped(part["expr"])):
                    if (listed := iri_list(conjunct)) is not None:
                        self.narrowed[(group, listed[0])] = listed[1]
                self._expression(part["expr"], group)
            else:
                raise Unsupported(f"{part.name} inside EXISTS")

    def _pattern(self, triple: tuple[object, object, object], group: int) -> None:
        subject, predicate, obj = (pattern_term(triple[0]), triple[1], pattern_term(triple[2]))
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
