"""What the timeline needs of each kind's query (sparql/timeline/<kind>.rq): kept as rows (a query the plan
cannot follow would be evaluated on every page), sorted by time then by its key (a key's rows together, one
event), filtered by the window on the columns every kind shares (`?robot`, `?human`, `?time`) or by facets."""

from __future__ import annotations

import pytest

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.timeline.kinds import FINDING, KINDS, query_name
from segb_server.backend.services.timeline.sentences import TELLERS
from segb_server.backend.services.views.kept_queries.plan import declared_key, plan_report

CATALOG = Catalog(PACKAGE_ROOT / "sparql")
QUERIES = CATALOG.under("timeline")


def test_every_kind_but_findings_has_a_query_and_a_teller() -> None:
    kept = [kind for kind in KINDS if kind != FINDING]
    assert sorted(query.name for query in QUERIES) == sorted(query_name(kind) for kind in kept)
    assert sorted(TELLERS) == sorted(kept)


@pytest.mark.parametrize("query", QUERIES, ids=lambda query: query.name)
def test_a_kinds_query_is_kept_sorted_by_time_then_key_and_filtered_by_the_window(query) -> None:  # type: ignore[no-untyped-def]
    plan = plan_report(query)  # raises Unsupported for what the rows cannot follow
    key = declared_key(query)
    assert plan.order[:2] == ["?time", key[0]]
    assert {"robot", "since", "until"} <= set(query.parameters)
    columns = {f.parameter: (f.column, f.op) for f in plan.column_filters}
    assert columns["since"] == ("?time", ">=") and columns["until"] == ("?time", "<=")
    facets = {f.parameter for f in plan.facet_filters}
    assert set(query.parameters) == set(columns) | facets
    assert columns.get("robot", ("?robot", "="))[0] == "?robot"
