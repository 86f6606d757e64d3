"""Users' queries checked outside the server process: the same verdicts as guard_query, a check stopped at its
query's deadline, queries too complex to parse refused before any parsing, and a checking process that died
started again."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from segb_server.backend.services.errors import InvalidQuery
from segb_server.backend.services.sparql.check_process import QUICK_SECONDS
from segb_server.backend.services.sparql.checkers import Checkers
from segb_server.backend.services.sparql.guard import (
    MAX_QUERY_TERMS,
    QueryTooComplex,
    guard_query,
    refuse_unparsable,
)
from segb_server.backend.services.sparql.limits import QueryLimits
from segb_server.backend.store.base import QueryTimeout

EVENTS = "http://amor-segb/events"
SLOW = "SELECT * WHERE {{ ?s ?p ?o FILTER(COALESCE({})) }}".format(",".join(["?o"] * (MAX_QUERY_TERMS - 10)))


@pytest.fixture(scope="module")
def checkers() -> Iterator[Checkers]:
    started = Checkers()
    yield started
    started.close()


def limits(seconds: float = 30) -> QueryLimits:
    return QueryLimits(seconds, 10)


@pytest.mark.parametrize(
    "query",
    [
        "PREFIX ex: <http://e/> SELECT ?s FROM <http://amor-segb/events> WHERE { ?s ex:p ?o } LIMIT 1",
        "ASK { ?s ?p ?o }",
        "CONSTRUCT WHERE { ?s ?p ?o }",
    ],
)
def test_an_accepted_query_is_checked_as_in_process(checkers: Checkers, query: str) -> None:
    assert checkers.check(query, EVENTS, limits()) == guard_query(query, EVENTS)


@pytest.mark.parametrize(
    "query",
    [
        "SELECT * WHERE {\n  ?s ?p \n}",
        "INSERT DATA { <http://e/a> <http://e/b> <http://e/c> }",
        "SELECT * WHERE { SERVICE <http://elsewhere/sparql> { ?s ?p ?o } }",
        "SELECT * FROM <http://other/graph> WHERE { ?s ?p ?o }",
    ],
)
def test_a_refused_query_is_refused_as_in_process(checkers: Checkers, query: str) -> None:
    with pytest.raises(InvalidQuery) as in_process:
        guard_query(query, EVENTS)
    for _ in range(2):  # the second verdict is the one remembered
        with pytest.raises(InvalidQuery) as elsewhere:
            checkers.check(query, EVENTS, limits())
        refused, expected = elsewhere.value, in_process.value
        assert (refused.message, refused.details) == (expected.message, expected.details)


def test_a_query_too_complex_to_parse_is_refused_before_parsing() -> None:
    many = "SELECT * WHERE {{ ?s ?p ?o FILTER(?o IN ({})) }}".format(",".join(["1"] * MAX_QUERY_TERMS))
    started = time.monotonic()
    with pytest.raises(QueryTooComplex) as refused:
        refuse_unparsable(many)
    assert time.monotonic() - started < 0.5
    assert refused.value.details["reason"] == "too_complex"
    assert refused.value.details["query_kind"] == "select"
    # IRIs are not operators, and long lists in VALUES cost rdflib little: neither counts.
    listed = " ".join(f"<http://e/{n}>" for n in range(3 * MAX_QUERY_TERMS))
    refuse_unparsable(f"SELECT * WHERE {{ VALUES ?o {{ {listed} }} ?s ?p ?o }}")


def test_a_check_past_the_deadline_is_stopped_and_the_next_one_is_quick(checkers: Checkers) -> None:
    started = time.monotonic()
    with pytest.raises(QueryTimeout) as stopped:
        checkers.check(SLOW, EVENTS, limits(1))
    assert stopped.value.seconds == 1
    assert time.monotonic() - started < 2
    started = time.monotonic()
    assert checkers.check("SELECT ?quick WHERE { ?quick ?p ?o }", EVENTS, limits()).form == "select"
    assert time.monotonic() - started < 1


def test_time_spent_before_the_check_counts_against_its_limit(checkers: Checkers) -> None:
    spent = QueryLimits(5, 10, started=time.monotonic() - 5)
    with pytest.raises(QueryTimeout):
        checkers.check("SELECT ?late WHERE { ?late ?p ?o }", EVENTS, spent)


def test_a_checking_process_that_died_is_started_again(checkers: Checkers) -> None:
    checkers.check("SELECT ?before WHERE { ?before ?p ?o }", EVENTS, limits())
    process = checkers._process
    assert process is not None and process.pid is not None
    os.kill(process.pid, signal.SIGKILL)
    process.join(timeout=10)
    assert checkers.check("SELECT ?after WHERE { ?after ?p ?o }", EVENTS, limits()).form == "select"
    assert checkers._process is not process


def test_a_check_longer_than_a_moment_still_gets_its_verdict(checkers: Checkers) -> None:
    # Its worker is given the lowest CPU priority after QUICK_SECONDS, and ended once it has answered.
    longish = "SELECT * WHERE {{ ?s ?p ?o FILTER(COALESCE({})) }}".format(",".join(["?o"] * 400))
    started = time.monotonic()
    assert checkers.check(longish, EVENTS, limits()).form == "select"
    assert time.monotonic() - started > QUICK_SECONDS
    assert checkers.check("SELECT ?next WHERE { ?next ?p ?o }", EVENTS, limits()).form == "select"


def test_a_worker_that_dies_while_checking_is_reported_not_hidden(checkers: Checkers) -> None:
    checkers.check("SELECT ?first WHERE { ?first ?p ?o }", EVENTS, limits())
    process = checkers._process
    assert process is not None and process.pid is not None
    with ThreadPoolExecutor(max_workers=1) as pool:
        checking = pool.submit(checkers.check, SLOW + " LIMIT 5", EVENTS, limits())
        time.sleep(1)  # it is being parsed (for seconds)
        for worker in Path(f"/proc/{process.pid}/task/{process.pid}/children").read_text().split():
            os.kill(int(worker), signal.SIGKILL)  # the way the system ends a process for want of memory
        with pytest.raises(QueryTooComplex, match="could not be checked"):
            checking.result(timeout=20)
    assert checkers.check("SELECT ?again WHERE { ?again ?p ?o }", EVENTS, limits()).form == "select"
