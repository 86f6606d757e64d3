"""How one query is kept current, told in words (`segb upkeep VIEW`): what identifies its rows, which of its
triple patterns a new triple can match and the steps from each back to the rows it changes, how its filters and
aggregates are served — or why it is evaluated in full on every request."""

from __future__ import annotations

import re

from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.views.kept_queries.facets import facet_patterns
from segb_server.backend.services.views.kept_queries.keys import chains
from segb_server.backend.services.views.kept_queries.layout import Layout
from segb_server.backend.services.views.kept_queries.plan import declared_key, plan_report
from segb_server.backend.services.views.kept_queries.plan_parts import Pattern, Unsupported
from segb_server.backend.vocabulary import compact


def describe(query: CatalogQuery) -> list[str]:
    """Lines telling how `query` is kept."""
    if query.same_as is not None:
        return [
            f"{query.name}: a preset of {query.same_as} — served from its rows (kept once), its own defaults bound "
            "when a page is read"
        ]
    try:
        declared_key(query)
        plan = plan_report(query)
        unit = plan.unit()
    except Unsupported as reason:
        return [f"{query.name}: evaluated in full on every request — {reason}"]
    layout = Layout("rows", plan, query.parameters, unit)
    lines = [f"{query.name}: kept as rows, replaced key by key as robots write"]
    lines += [
        f"  rows identified by ?{unit}" + (f", grouped by {' '.join(plan.group_by)}" if plan.is_aggregate else "")
    ]
    order = plan.group_by if plan.is_aggregate else plan.order
    lines.append(f"  stored in the order {' '.join(order)} (an index on the sort key; pages are keyset-paged)")
    for condition in plan.column_filters:
        column = condition.column[1:]
        how = (
            "a range of the sort key's index"
            if column == layout.sorted_by
            else f"an index on {condition.column} (with the sort key)"
        )
        lines.append(f"  filter {condition.parameter}: {condition.column} {condition.op} ?, from {how}")
    for facet in plan.facet_filters:
        lines.append(
            f"  filter {facet.parameter}: the values each {facet.anchor} has, kept as pairs that only grow: a new "
            "triple adds the pairs it joins (its pattern bound to it, the rest of the EXISTS joined)"
        )
    for aggregate in plan.aggregates:
        if aggregate.function == "count" and aggregate.argument == f"?{unit}":
            how = "moved by the keys that join or leave a group"
        else:
            how = f"read from an index on ({' '.join(plan.group_by)}, {aggregate.argument})"
        distinct = "DISTINCT " if aggregate.distinct else ""
        lines.append(f"  {aggregate.output} = {aggregate.function.upper()}({distinct}{aggregate.argument}): {how}")
    lines.append(
        "  a new triple matching a pattern changes the rows of the keys these steps reach (followed among the "
        "batch's own triples while they go from resources the batch introduced, else asked of the store):"
    )
    ignored = facet_patterns(plan)
    for pattern in plan.patterns:
        if pattern in ignored:
            continue
        matched = _joined([pattern], plan.allowed_in([pattern]))
        if f"?{unit}" in pattern.variables():
            lines.append(f"    {matched}  → holds ?{unit}")
            continue
        for chain in chains(plan, pattern, f"?{unit}"):
            lines.append(f"    {matched}  → from {' '.join(chain.names)}: {_short(chain.steps)}")
    if plan.required:
        lines.append(
            "  a key the batch introduced is evaluated only when what every row needs can match among the batch's "
            f"triples: {_joined(plan.required, plan.allowed_in(plan.required))}"
        )
    for body in plan.exclusions_of(f"?{unit}"):
        lines.append(
            "  and not when what no row may have matches among them (NOT EXISTS): "
            f"{_joined(body, plan.allowed_in(body))}"
        )
    return lines


def describe_others() -> list[str]:
    """The kept views that are not queries kept as rows."""
    return [
        "graph index: every link and the literals that name and place nodes, kept from each batch's triples (a node's "
        "kind, time and label computed again when a fact about it, or about the activity it borrows its time from, "
        "arrives): backend/services/views/graph_index.py",
        "SHACL rules' findings (rules/*.ttl): the shapes checked again on the nodes a batch's triples touch: "
        "backend/services/views/shape_view.py",
    ]


def _joined(patterns: list[Pattern], allowed: dict[str, frozenset[str]]) -> str:
    """Patterns as SPARQL, with the only values their VALUES or `IN (…)` allow a variable."""
    text = " ".join(_short(pattern.sparql()) for pattern in patterns)
    used = {variable for pattern in patterns for variable in pattern.variables()}
    narrowed = [
        f"{variable} in {', '.join(_short(value) for value in sorted(values))}"
        for variable, values in sorted(allowed.items())
        if variable in used
    ]
    return text + (f" ({'; '.join(narrowed)})" if narrowed else "")


def _short(sparql: str) -> str:
    """IRIs of the known namespaces as prefixed names (`<http://schema.org/text>` → `schema:text`)."""
    return _IRI.sub(lambda found: compact(found.group(1)), sparql)


_IRI = re.compile(r"<([^<>\s]+)>")
