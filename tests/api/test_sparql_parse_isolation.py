"""A user's query that takes rdflib long to parse holds no one else up: a query of pathological size is refused at
once with a 413, one that is merely slow to parse is stopped at SPARQL_TIMEOUT_SECONDS with a 503 (its parse
counts against the time limit), and meanwhile another user's small query answers at once. Over a real socket,
the slow ones in threads of their own."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.api.app import create_app
from segb_server.backend.services.sparql.guard import MAX_QUERY_BYTES, MAX_QUERY_TERMS
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.live_server import LiveServer

TIMEOUT = 3
EX = "http://example.org/parse/"


def huge_disjunction(variant: int) -> str:
    """24,000 terms joined by ||, under the size limit: rdflib would parse it for tens of seconds."""
    terms = "||".join(["?o"] * 24_000)
    return f"SELECT * WHERE {{ ?s ?p ?o FILTER({terms}) }} LIMIT {variant + 1}"


def long_coalesce(variant: int) -> str:
    """Just under the pre-check's limit, and still several seconds of parsing (far past TIMEOUT)."""
    arguments = ",".join(["?o"] * (MAX_QUERY_TERMS - 10))
    return f"SELECT * WHERE {{ ?s ?p ?o FILTER(COALESCE({arguments})) }} LIMIT {variant + 1}"


def small(limit: int) -> str:
    return f"SELECT ?s ?o WHERE {{ ?s ?p ?o }} ORDER BY ?o LIMIT {limit}"


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    store = OxigraphStore("http://amor-segb/events")
    predicate = NamedNode(EX + "value")
    store.apply([Quad(NamedNode(f"{EX}thing/{n}"), predicate, Literal(str(n))) for n in range(5)], 0)
    with LiveServer(create_app(make_settings(sparql_timeout_seconds=TIMEOUT), store=store)) as live:
        yield live.url
    store.close()


def ask(url: str, query: str) -> tuple[httpx.Response, float]:
    started = time.monotonic()
    answer = httpx.post(f"{url}/sparql", data={"query": query}, timeout=120)
    return answer, time.monotonic() - started


def test_the_pathological_query_is_within_the_size_limit() -> None:
    query = huge_disjunction(0)
    assert 90_000 < len(query.encode()) <= MAX_QUERY_BYTES  # refused for its complexity, not its size


@pytest.mark.parametrize("slow", [huge_disjunction, long_coalesce], ids=["refused", "stopped"])
def test_a_slow_parse_holds_up_no_other_query(server: str, slow: Callable[[int], str]) -> None:
    warm, _ = ask(server, small(2))  # the first query starts the checking and query processes
    assert warm.status_code == 200, warm.text

    with ThreadPoolExecutor(max_workers=3) as pool:
        slow_ones = [pool.submit(ask, server, slow(n)) for n in range(3)]
        time.sleep(0.5)  # the three are being checked now
        answer, elapsed = ask(server, small(3))
        assert answer.status_code == 200, answer.text
        assert [row["o"]["value"] for row in answer.json()["results"]["bindings"]] == ["0", "1", "2"]
        assert elapsed < 1, f"a small query took {elapsed:.2f} s beside three slow ones"
        results = [future.result() for future in slow_ones]

    for refused, took in results:
        body = refused.json()
        if slow is huge_disjunction:
            assert (refused.status_code, body["error"], body["reason"]) == (413, "payload_too_large", "too_complex")
            assert f"the limit is {MAX_QUERY_TERMS}" in body["detail"]
            assert took < 1, f"refused after {took:.1f} s"
        else:
            assert (refused.status_code, body["error"], body["timeout_seconds"]) == (503, "query_timeout", TIMEOUT)
            assert took < TIMEOUT + 1.5, f"stopped after {took:.1f} s"


def test_a_slow_parse_is_stopped_on_every_endpoint_that_checks_queries(server: str) -> None:
    reference = httpx.get(f"{server}/query", params={"query": long_coalesce(7)}, timeout=60)
    assert (reference.status_code, reference.json()["error"]) == (503, "query_timeout")
    validated = httpx.post(f"{server}/query/validate", json={"query": huge_disjunction(7)}, timeout=60)
    assert validated.status_code == 200
    assert (validated.json()["valid"], validated.json()["reason"]) == (False, "too_complex")
    stopped = httpx.post(f"{server}/query/validate", json={"query": long_coalesce(8)}, timeout=60)
    assert (stopped.status_code, stopped.json()["error"]) == (503, "query_timeout")
    assert httpx.post(f"{server}/sparql", data={"query": small(1)}, timeout=10).status_code == 200
