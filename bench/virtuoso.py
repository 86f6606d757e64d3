"""Virtuoso measured directly: the cost of one small insert over HTTP (the floor under any server in front
of it), of a report's query for one row key (what keeping a report current asks after each batch of posts),
and triple counts of a graph (so a server without an export, like the baseline, can be checked)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import httpx
from pyoxigraph import NamedNode, RdfFormat, parse
from tqdm import tqdm

from bench.measure import Latency
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, Catalog
from segb_server.backend.store.terms import bind_rows, bind_values
from tests.support.virtuoso import VirtuosoProcess

MESSAGE = "http://schema.org/Message"
RESULTS_XML = "application/sparql-results+xml"  # as the server reads Virtuoso's answers
KEYED_REPORT = "reports/conversations"  # the report with the most OPTIONALs: the longest to plan


def _client(virtuoso: VirtuosoProcess) -> httpx.Client:
    # As backend/store/virtuoso.py: digest auth, one kept-alive connection (the challenge is reused).
    return httpx.Client(auth=httpx.DigestAuth(virtuoso.user, virtuoso.password), timeout=60)


def _update(client: httpx.Client, endpoint: str, sparql: str) -> None:
    response = client.post(
        endpoint, content=sparql.encode(), headers={"Content-Type": "application/sparql-update; charset=utf-8"}
    )
    response.raise_for_status()


def count_graph(virtuoso: VirtuosoProcess, graph: str) -> int:
    """Triples in one named graph."""
    with _client(virtuoso) as client:
        response = client.post(
            virtuoso.endpoint,
            data={"query": f"SELECT (COUNT(*) AS ?n) WHERE {{ GRAPH <{graph}> {{ ?s ?p ?o }} }}"},
            headers={"Accept": "application/sparql-results+json"},
        )
        response.raise_for_status()
        return int(response.json()["results"]["bindings"][0]["n"]["value"])


@dataclass(frozen=True)
class Floor:
    """Latency of bare requests to Virtuoso, without any server in front."""

    triples_per_insert: float
    ask: Latency
    insert_data: Latency
    conditional_insert: Latency
    # The conversations report for one message: a text Virtuoso has not seen (another message each time, as
    # after each batch of posts), and the same text asked again (its plan kept). None in runs before them.
    report_new_key: Latency | None = None
    report_same_key: Latency | None = None


def measure_floor(virtuoso: VirtuosoProcess, graph: str, payloads: list[str]) -> Floor:
    """Each payload's triples (new every time) written once with `INSERT DATA` and once, into another
    graph, with the conditional insert the SEGB adapter uses; and a trivial `ASK {}` as the round trip."""
    batches = [
        [f"{quad.subject} {quad.predicate} {quad.object}" for quad in parse(payload.encode(), RdfFormat.TURTLE)]
        for payload in payloads
    ]
    timings: dict[str, list[float]] = {"ask": [], "insert_data": [], "conditional": []}
    with _client(virtuoso) as client:
        for lines in tqdm(batches, desc="virtuoso floor", leave=False):
            begin = time.perf_counter()
            client.post(virtuoso.endpoint, data={"query": "ASK {}"}).raise_for_status()
            timings["ask"].append(time.perf_counter() - begin)
            body = "".join(f"{line} .\n" for line in lines)
            begin = time.perf_counter()
            _update(client, virtuoso.endpoint, f"INSERT DATA {{ GRAPH <{graph}/data> {{\n{body}}} }}")
            timings["insert_data"].append(time.perf_counter() - begin)
            rows = "".join(f"({line})\n" for line in lines)
            target = f"<{graph}/conditional>"
            begin = time.perf_counter()
            _update(
                client,
                virtuoso.endpoint,
                f"INSERT {{ GRAPH {target} {{ ?s ?p ?o }} }}\nWHERE {{ VALUES (?s ?p ?o) {{\n{rows}}}\n"
                f"  FILTER NOT EXISTS {{ GRAPH {target} {{ ?s ?p ?o }} }} }}",
            )
            timings["conditional"].append(time.perf_counter() - begin)
        messages = [
            str(quad.subject)
            for payload in payloads
            for quad in parse(payload.encode(), RdfFormat.TURTLE)
            if quad.object == NamedNode(MESSAGE)
        ]
        new_key, same_key = _report_for_one_key(client, virtuoso.endpoint, messages)
    return Floor(
        triples_per_insert=sum(map(len, batches)) / len(batches),
        ask=Latency.of(timings["ask"]),
        insert_data=Latency.of(timings["insert_data"]),
        conditional_insert=Latency.of(timings["conditional"]),
        report_new_key=new_key,
        report_same_key=same_key,
    )


def _report_for_one_key(client: httpx.Client, endpoint: str, keys: list[str]) -> tuple[Latency, Latency]:
    """The report's query bound to each key in turn as the server binds it on Virtuoso, each asked twice: first
    as a new text, then the same text again."""
    query = Catalog(PACKAGE_ROOT / "sparql").get(KEYED_REPORT)
    text = bind_values(query.text, {PARAMETER_VARIABLE_PREFIX + name: None for name in query.parameters})
    first: list[float] = []
    again: list[float] = []
    for key in tqdm(keys, desc="virtuoso report for one key", leave=False):
        bound = bind_rows(text, ["message"], [[NamedNode(key.strip("<>"))]], wrap=True)
        for timings in (first, again):
            begin = time.perf_counter()
            response = client.post(endpoint, data={"query": bound}, headers={"Accept": RESULTS_XML})
            response.raise_for_status()
            timings.append(time.perf_counter() - begin)
    return Latency.of(first), Latency.of(again)
