"""Single nodes of rdflib's algebra of a query (and of the groups it leaves as parsed inside EXISTS), read for
the plan: a pattern's terms, a group's triples, the conjuncts of a filter, a filter a parameter switches on."""

from __future__ import annotations

from rdflib.plugins.sparql.parserutils import CompValue
from rdflib.term import BNode, Identifier, URIRef, Variable

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX
from segb_server.backend.services.views.kept_queries.plan_parts import ColumnFilter, Unsupported


def triples_of(graph: CompValue) -> tuple[str, ...]:
    """A group's triples as text: the same for the group as written and as the translation left it."""
    return tuple(
        str([str(term) for term in triples])
        for part in graph.get("part") or []
        if part.name == "TriplesBlock"
        for triples in part["triples"]
    )


def pattern_term(term: object) -> str:
    """A pattern's subject or object as the plan writes it: "?x" for a variable, N-Triples for a term."""
    if isinstance(term, Variable):
        return f"?{term}"
    if isinstance(term, BNode):
        raise Unsupported("blank nodes in patterns")
    if isinstance(term, Identifier):
        return term.n3()
    raise Unsupported(f"the term {term!r}")


def unwrapped(expression: object) -> object:
    """An expression as parsed (a FILTER inside EXISTS) without its wrappers of one term (an "OR" of one
    "AND" of one comparison…), as the algebra has it elsewhere."""
    while (
        isinstance(expression, CompValue)
        and expression.name.endswith("Expression")
        and not dict.get(expression, "other")  # (CompValue's own `get` answers a missing key with its name)
        and "expr" in expression
    ):
        expression = expression["expr"]
    return expression


def iri_list(expression: object) -> tuple[str, frozenset[str]] | None:
    """`?x IN (<a>, <b>, …)`, all IRIs: (?x, their N-Triples texts)."""
    expression = unwrapped(expression)
    if not (isinstance(expression, CompValue) and expression.name == "RelationalExpression"):
        return None
    variable = unwrapped(expression.get("expr"))
    others = [unwrapped(other) for other in dict.get(expression, "other") or []]
    if expression.get("op") != "IN" or not isinstance(variable, Variable) or not others:
        return None
    iris = [other for other in others if isinstance(other, URIRef)]
    if len(iris) != len(others):
        return None
    return f"?{variable}", frozenset(iri.n3() for iri in iris)


def has_filter(graph: CompValue) -> bool:
    return any(part.name == "Filter" for part in graph.get("part") or [])


def is_not_exists(expression: object) -> bool:
    return isinstance(expression, CompValue) and expression.name == "Builtin_NOTEXISTS"


def conjuncts(expression: object) -> list[object]:
    if isinstance(expression, CompValue) and expression.name == "ConditionalAndExpression":
        return [expression["expr"], *(expression.get("other") or [])]
    return [expression]


def switched_filter(expression: object) -> tuple[str, ColumnFilter | list[CompValue]] | None:
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


def exists_graphs(expression: object) -> list[CompValue]:
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
