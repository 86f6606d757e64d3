"""The time limit and row cap of user SPARQL (/sparql and /query), through the whole app in process, on the embedded
store and on a real Virtuoso: long answers are cut and flagged, slow queries stopped with a 503 naming the timeout, and
ordinary queries answer exactly as before."""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Iterator

import httpx
import pytest
from pyoxigraph import Literal, NamedNode, Quad, RdfFormat, parse

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store
from tests.conftest import make_settings
from tests.support.in_process import InProcess, Server, http

EX = "http://example.org/limits/"
EVERYTHING = "SELECT ?s ?o WHERE { ?s ?p ?o } ORDER BY ?s"
CROSS_JOIN = "SELECT * WHERE { ?a ?p ?b . ?c ?q ?d }"  # rows = triples², produced as they are found


def fill(store: Store, triples: int) -> None:
    predicate = NamedNode(EX + "value")
    store.apply([Quad(NamedNode(f"{EX}thing/{n:05d}"), predicate, Literal(str(n))) for n in range(triples)], 0)


def serve(store: Store, **limits: object) -> Iterator[InProcess]:
    with InProcess(create_app(make_settings(**limits), store=store)) as server:
        yield server


@pytest.fixture
def capped(store: Store) -> Iterator[InProcess]:
    """Thirty triples behind a cap of ten rows."""
    fill(store, 30)
    yield from serve(store, sparql_max_rows=10)


def get(server: Server, path: str, query: str, **params: str) -> httpx.Response:
    return http(server, "GET", f"{path}", params={"query": query, **params})


def test_an_answer_over_the_row_cap_is_cut_and_flagged(capped: InProcess) -> None:
    answer = get(capped.client, "/sparql", EVERYTHING)
    assert answer.status_code == 200, answer.text
    bindings = answer.json()["results"]["bindings"]
    assert [row["s"]["value"] for row in bindings] == [f"{EX}thing/{n:05d}" for n in range(10)]  # order kept
    assert answer.headers["x-segb-truncated"] == "true"
    assert answer.headers["x-segb-max-rows"] == "10"

    as_csv = get(capped.client, "/sparql", EVERYTHING, format="csv")
    rows = list(csv.reader(io.StringIO(as_csv.text)))
    assert rows[0] == ["s", "o"] and len(rows) == 11
    assert as_csv.headers["x-segb-truncated"] == "true"


def test_graph_answers_and_the_reference_query_are_capped_too(capped: InProcess) -> None:
    graph = get(capped.client, "/sparql", "CONSTRUCT WHERE { ?s ?p ?o }", format="ntriples")
    assert graph.status_code == 200, graph.text
    assert len(list(parse(graph.content, RdfFormat.N_TRIPLES))) == 10
    assert graph.headers["x-segb-truncated"] == "true"

    reference = get(capped.client, "/query", EVERYTHING)
    assert reference.status_code == 200, reference.text
    subjects = "http://example.org/s"  # the reference's encoding: one ex:<variable> triple per bound cell
    rows = [quad for quad in parse(reference.content, RdfFormat.TURTLE) if quad.predicate.value == subjects]
    assert len(rows) == 10
    assert reference.headers["x-segb-truncated"] == "true"


def test_an_answer_at_the_cap_exactly_is_not_flagged(capped: InProcess) -> None:
    answer = get(capped.client, "/sparql", EVERYTHING + " LIMIT 10")
    assert len(answer.json()["results"]["bindings"]) == 10
    assert "x-segb-truncated" not in answer.headers


def test_ordinary_queries_answer_in_full_under_the_default_limits(store: Store) -> None:
    fill(store, 300)
    for server in serve(store):
        answer = get(server.client, "/sparql", EVERYTHING)
        ask = get(server.client, "/sparql", "ASK { ?s ?p ?o }")
    assert answer.status_code == 200
    assert len(answer.json()["results"]["bindings"]) == 300
    assert "x-segb-truncated" not in answer.headers
    assert ask.json()["boolean"] is True


def test_a_query_past_the_time_limit_is_stopped_with_503(store: Store) -> None:
    fill(store, 2000)  # the cross join has four million rows
    for server in serve(store, sparql_timeout_seconds=0.5, sparql_max_rows=10_000_000):
        started = time.monotonic()
        answer = get(server.client, "/sparql", CROSS_JOIN)
        elapsed = time.monotonic() - started
        reference = get(server.client, "/query", CROSS_JOIN)
    for server in serve(store):  # the default limit: a store still winding the stopped query down may take > 0.5 s
        after = get(server.client, "/sparql", "ASK { ?s ?p ?o }")
    assert answer.status_code == 503, answer.text[:300]
    body = answer.json()
    assert body["error"] == "query_timeout" and body["status"] == 503
    assert body["timeout_seconds"] == 0.5
    assert "SPARQL_TIMEOUT_SECONDS" in body["detail"]
    assert elapsed < 5, f"stopped only after {elapsed:.1f} s"
    assert reference.status_code == 503 and reference.json()["error"] == "query_timeout"
    assert after.status_code == 200 and after.json()["boolean"] is True  # the store is fine afterwards


def test_a_sorted_page_past_what_the_store_sorts_is_refused_by_name(store: Store) -> None:
    """Virtuoso sorts at most 10,000 rows for an answer with a LIMIT (offset included): such a user query is the
    user's to change, so it is a 400 saying why, not a 502 as if the store had failed."""
    fill(store, 30)
    for server in serve(store):
        within = get(server.client, "/sparql", EVERYTHING + " LIMIT 10000")
        beyond = get(server.client, "/sparql", EVERYTHING + " LIMIT 5000 OFFSET 5001")
    assert within.status_code == 200 and len(within.json()["results"]["bindings"]) == 30
    if store.max_sorted_rows is None:
        assert beyond.status_code == 200, beyond.text[:300]
        assert beyond.json()["results"]["bindings"] == []
    else:
        assert beyond.status_code == 400, beyond.text[:300]
        body = beyond.json()
        assert body["error"] == "invalid_query", body
        assert "10000" in body["detail"] and "offset" in body["detail"], body


@pytest.mark.virtuoso
def test_virtuoso_stops_an_aggregate_at_the_time_limit(virtuoso) -> None:  # type: ignore[no-untyped-def]
    """An aggregate yields no row before it is done: Virtuoso's own limit (its `timeout` parameter) stops it."""
    from tests.conftest import virtuoso_store

    store = virtuoso_store(virtuoso)
    try:
        fill(store, 2000)
        for server in serve(store, sparql_timeout_seconds=0.5):
            started = time.monotonic()
            answer = get(server.client, "/sparql", "SELECT (COUNT(*) AS ?n) WHERE { ?a ?p ?b . ?c ?q ?d . ?e ?r ?f }")
            elapsed = time.monotonic() - started
    finally:
        store.clear()
        store.close()
    assert answer.status_code == 503, answer.text[:300]
    assert answer.json()["error"] == "query_timeout"
    assert elapsed < 10
