"""A kept report's rows are its query's answer for one key, but the views ask the store for many keys at once (a
VALUES block of a batch's keys), and which keys share a question depends on how posts fall into batches. So each
kept query, asked for every key at once and in full, must answer for each key exactly what it answers for that
key alone, on both stores. Virtuoso 7 did not for an OPTIONAL of a UNION of BINDs (the timeline's activity
kinds): asked for several activities, it gave an activity the kinds of another, or none, and whether a timeline
named an activity's kind depended on how its posts were batched. The audit rules' SPARQL rules are kept queries
too, and are asked the same way."""

from __future__ import annotations

from collections import Counter
from itertools import groupby

import pytest
from pyoxigraph import Quad, RdfFormat, parse

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.sparql.catalog import Catalog, CatalogQuery
from segb_server.backend.services.views.kept_queries.plan import plan_report
from segb_server.backend.services.views.kept_queries.plan_parts import Unsupported
from segb_server.backend.services.views.kept_queries.projection import kept_text
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.terms import bind_texts, term_text
from tests.support.investigation import incident
from tests.support.rule_scenarios import troubled

CATALOG = Catalog(PACKAGE_ROOT / "sparql")
RULES = RuleCatalog(PACKAGE_ROOT / "rules")
Answer = dict[str, Counter[tuple[tuple[str, str], ...]]]


def kept_queries() -> list[tuple[CatalogQuery, str, str]]:
    """(query, its unit variable, the text its rows are the answer of, parameters unbound) for every kept query."""
    kept = []
    rules = [rule.query for rule in RULES.sparql() if rule.query is not None]
    for query in [*CATALOG.under("reports"), *CATALOG.under("timeline"), *rules]:
        try:
            plan = plan_report(query)
        except Unsupported:
            continue  # evaluated in full on every request: never asked by keys
        kept.append((query, plan.unit(), kept_text(query, plan)))
    return kept


KEPT = kept_queries()


def answer(store: Store, text: str, unit: str, keys: list[str] | None = None) -> Answer:
    """The rows of each key: the query in full (keys None), or bound to `keys` as the views bind them."""
    bound = text if keys is None else bind_texts(text, [unit], [[key] for key in keys], wrap=store.wraps_values)
    rows = [tuple(sorted((name, term_text(value)) for name, value in row.items())) for row in select(store, bound).rows]
    keyed = sorted((dict(row)[unit], row) for row in rows if unit in dict(row))
    return {key: Counter(row for _, row in group) for key, group in groupby(keyed, key=lambda pair: pair[0])}


@pytest.fixture
def scenario_store(store: Store) -> Store:
    """The store holding the incident's graph and the troubled scenario's (one slip of each kind the audit rules
    look for), as their robots last published them."""
    scenarios = [incident(), troubled()[0]]
    for scenario in scenarios:
        scenario.run_steps()
    quads = [
        Quad(triple.subject, triple.predicate, triple.object)
        for scenario in scenarios
        for turtle in scenario.published_turtle()
        for triple in parse(turtle, RdfFormat.TURTLE)
    ]
    store.apply(quads, 1)
    return store


@pytest.mark.parametrize(("query", "unit", "text"), KEPT, ids=[query.name for query, _, _ in KEPT])
def test_a_kept_query_asked_for_many_keys_answers_for_each_what_it_answers_for_it_alone(
    scenario_store: Store, query: CatalogQuery, unit: str, text: str
) -> None:
    in_full = answer(scenario_store, text, unit)
    assert in_full, "the scenarios give this query rows"
    alone = {key: rows for key in in_full for key, rows in answer(scenario_store, text, unit, [key]).items()}
    assert answer(scenario_store, text, unit, sorted(in_full)) == alone, "asked for every key at once"
    assert in_full == alone, "evaluated in full"
