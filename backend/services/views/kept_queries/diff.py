"""A kept view's rows beside its query evaluated in full (`segb upkeep --diff VIEW [KEY]`): a newcomer tells a
wrong row (the upkeep missed a change: the two differ) from a wrong query (they agree, and both are wrong) in one
command."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.sparql.paging import evaluated_page
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.services.views.kept_queries.projection import KeptQueries
from segb_server.backend.store.base import Store

PAGE = 10_000

Row = dict[str, JsonValue]


@dataclass(frozen=True)
class ViewDifference:
    """The rows only the kept view has, and those only the full evaluation has (each as many times as it is
    missing), for every key or for one."""

    view: str
    unit: str  # the column whose values identify a row's key
    kept: int  # rows compared on each side
    evaluated: int
    only_kept: list[Row]
    only_evaluated: list[Row]

    @property
    def same(self) -> bool:
        return not self.only_kept and not self.only_evaluated


class NotKept(Exception):
    """The view is not kept as rows here (evaluated in full, or not built yet): nothing to compare."""


def diff_view(kept: KeptQueries, store: Store, query: CatalogQuery, key: str | None = None) -> ViewDifference:
    """Compare the rows `kept` holds for `query` (its default parameters bound) with the query evaluated in full,
    restricted to the rows of `key` (a value of the view's key column) when given; blocking."""
    projection = kept.reports.get(query.name)
    if projection is None:
        reason = kept.unsupported.get(query.name, "it is not among the kept views")
        raise NotKept(f"{query.name} is not kept as rows: {reason}")
    bindings = query.bindings({})
    bound = {name: bindings[PARAMETER_VARIABLE_PREFIX + name] for name in query.parameters}
    rows_kept: list[Row] = []
    after: str | None = None
    while True:
        page = kept.page(query.name, bound, PAGE, 0, after)
        if page is None:
            raise NotKept(f"{query.name}'s rows are not built yet")
        rows_kept += page.rows
        if not page.has_more:
            break
        after = page.after
    result = evaluated_page(store, query.text, bindings, 1 << 62, 0)
    columns = kept.columns(query.name)
    rows_evaluated = [{column: json_value(row.get(column)) for column in columns} for row in result.rows]
    unit = projection.unit
    if key is not None:
        rows_kept = [row for row in rows_kept if row.get(unit) == key]
        rows_evaluated = [row for row in rows_evaluated if row.get(unit) == key]
    on_kept, on_evaluated = Counter(map(_frozen, rows_kept)), Counter(map(_frozen, rows_evaluated))
    return ViewDifference(
        query.name,
        unit,
        len(rows_kept),
        len(rows_evaluated),
        [dict(row) for row in (on_kept - on_evaluated).elements()],
        [dict(row) for row in (on_evaluated - on_kept).elements()],
    )


def _frozen(row: Row) -> tuple[tuple[str, JsonValue], ...]:
    return tuple(sorted(row.items()))


def told(difference: ViewDifference) -> list[str]:
    """The comparison in words."""
    head = (
        f"{difference.view}: {difference.kept} rows kept, {difference.evaluated} evaluated in full "
        f"(rows keyed by ?{difference.unit})"
    )
    if difference.same:
        return [head, "  the same rows: if one is wrong, the query is (its .rq file, or a rule of reading it uses)"]
    lines = [head, "  they differ: the upkeep missed a change (a wrong row, not a wrong query)"]
    lines += [f"  only kept:     {row}" for row in difference.only_kept]
    lines += [f"  only in full:  {row}" for row in difference.only_evaluated]
    return lines
