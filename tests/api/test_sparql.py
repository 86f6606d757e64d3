"""The read-only SPARQL endpoints through the whole app in process (over real HTTP for rdflib's client), on the embedded
store and on a real Virtuoso, filled by the real PyPI client: standard clients and parsers read every result format, and
nothing that writes or reaches outside the events graph gets through."""

from __future__ import annotations

import csv
import io
import json
import xml.etree.ElementTree as ElementTree
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import httpx
import pytest
from pyoxigraph import BlankNode, Literal, NamedNode, RdfFormat, Triple, parse
from rdflib import Graph
from rdflib.plugins.stores.sparqlstore import SPARQLStore

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from segb_server.backend.services.sparql.guard import MAX_QUERY_BYTES
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import STORE_KINDS, make_settings, virtuoso_store
from tests.support.in_process import InProcess, Server, http
from tests.support.live_server import LiveServer
from tests.support.scenarios import Scenario, lobby

FOAF = "http://xmlns.com/foaf/0.1/"
EX = "http://example.org/"
RESULTS_NS = {"r": "http://www.w3.org/2005/sparql-results#"}
NAMES = f"PREFIX foaf: <{FOAF}>\nSELECT ?human ?name WHERE {{ ?human foaf:firstName ?name }} ORDER BY ?name"
NAME_TRIPLES = f"PREFIX foaf: <{FOAF}>\nCONSTRUCT {{ ?h foaf:firstName ?n }} WHERE {{ ?h foaf:firstName ?n }}"


@dataclass
class Published:
    server: Server  # a live server's URL, or an in-process app's client
    store: Store
    scenario: Scenario

    def get(self, path: str, **options: Any) -> httpx.Response:
        return http(self.server, "GET", path, **options)

    def post(self, path: str, **options: Any) -> httpx.Response:
        return http(self.server, "POST", path, **options)

    def iri(self, name: str) -> str:
        return str(self.scenario.iris[name])

    def name_rows(self) -> list[tuple[str, str]]:
        """What NAMES must answer, in its ORDER BY order."""
        return [(self.iri("juan"), "Juan"), (self.iri("maria"), "Maria")]

    def name_triples(self) -> set[Triple]:
        first_name = NamedNode(FOAF + "firstName")
        return {
            Triple(NamedNode(self.iri(human)), first_name, Literal(name, language="en"))
            for human, name in (("juan", "Juan"), ("maria", "Maria"))
        }


@pytest.fixture(scope="module", params=STORE_KINDS)
def published(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Published]:
    """The lobby published once per store for this module's tests, which only read it (those that try to write
    check that nothing changed)."""
    if request.param == "virtuoso":
        store: Store = virtuoso_store(request.getfixturevalue("virtuoso"))
    else:
        store = OxigraphStore("http://amor-segb/events", tmp_path_factory.mktemp("sparql") / "oxigraph")
    with InProcess(create_app(make_settings(), store=store)) as api:
        scenario = lobby()
        scenario.publish_all(api.client)
        yield Published(api.client, store, scenario)
    if request.param == "virtuoso":
        store.clear()
    store.close()


@pytest.fixture
def published_live(store: Store) -> Iterator[Published]:
    """The lobby over real HTTP, for clients with HTTP libraries of their own."""
    with LiveServer(create_app(make_settings(), store=store)) as live:
        scenario = lobby()
        scenario.publish_all(live.url)
        yield Published(live.url, store, scenario)


def sparql(server: Server, query: str, accept: str | None = None, **params: str) -> httpx.Response:
    headers = {"Accept": accept} if accept else {}
    return http(server, "GET", "/sparql", params={"query": query, **params}, headers=headers)


# --- standard parsers, one per result format --------------------------------------------------------------


def json_rows(body: bytes) -> list[tuple[str, ...]]:
    document = json.loads(body)
    names = document["head"]["vars"]
    return [tuple(binding[name]["value"] for name in names) for binding in document["results"]["bindings"]]


def xml_rows(body: bytes) -> list[tuple[str, ...]]:
    root = ElementTree.fromstring(body)
    names = [variable.get("name") for variable in root.findall("r:head/r:variable", RESULTS_NS)]
    rows = []
    for result in root.findall("r:results/r:result", RESULTS_NS):
        values = {binding.get("name"): binding[0].text for binding in result.findall("r:binding", RESULTS_NS)}
        rows.append(tuple(values[name] for name in names))
    return rows  # type: ignore[return-value]


def csv_rows(body: bytes) -> list[tuple[str, ...]]:
    return [tuple(row) for row in list(csv.reader(io.StringIO(body.decode())))[1:]]


def tsv_rows(body: bytes) -> list[tuple[str, ...]]:
    """TSV cells are terms in Turtle syntax: read each one with the N-Triples parser."""

    def term_value(cell: str) -> str:
        (quad,) = parse(f"<{EX}s> <{EX}p> {cell} .".encode(), RdfFormat.N_TRIPLES)
        return quad.object.value

    lines = body.decode().splitlines()[1:]
    return [tuple(term_value(cell) for cell in line.split("\t")) for line in lines if line]


SOLUTION_FORMATS: list[tuple[str, str, Callable[[bytes], list[tuple[str, ...]]]]] = [
    ("json", "application/sparql-results+json", json_rows),
    ("xml", "application/sparql-results+xml", xml_rows),
    ("csv", "text/csv", csv_rows),
    ("tsv", "text/tab-separated-values", tsv_rows),
]
GRAPH_FORMATS = [
    ("turtle", "text/turtle"),
    ("ntriples", "application/n-triples"),
    ("jsonld", "application/ld+json"),
    ("rdfxml", "application/rdf+xml"),
]


def triples(response: httpx.Response) -> set[Triple]:
    media_type = response.headers["content-type"].split(";")[0]
    return {quad.triple for quad in parse(response.content, RdfFormat.from_media_type(media_type))}


# --- standard clients and formats ------------------------------------------------------------------------


def test_rdflib_sparqlstore_runs_a_select_over_every_protocol_binding(published_live: Published) -> None:
    endpoint = f"{published_live.server}/sparql"
    for method, return_format in (("GET", "xml"), ("POST", "json"), ("POST_FORM", "xml"), ("GET", "csv")):
        graph = Graph(store=SPARQLStore(endpoint, method=method, returnFormat=return_format))
        rows = [(str(row.human), str(row.name)) for row in graph.query(NAMES)]  # type: ignore[union-attr]
        assert rows == published_live.name_rows(), (method, return_format)
    graph = Graph(store=SPARQLStore(endpoint))
    assert len(graph.query(NAME_TRIPLES)) == 2


@pytest.mark.parametrize(("name", "media_type", "read_rows"), SOLUTION_FORMATS, ids=[f[0] for f in SOLUTION_FORMATS])
def test_every_select_format_parses_to_the_same_rows(
    published: Published, name: str, media_type: str, read_rows: Callable[[bytes], list[tuple[str, ...]]]
) -> None:
    by_accept = sparql(published.server, NAMES, accept=media_type)
    by_parameter = published.post(
        "/sparql",
        params={"format": name},
        content=NAMES.encode(),
        headers={"Content-Type": "application/sparql-query"},
    )
    by_form = published.post("/sparql", data={"query": NAMES}, headers={"Accept": f"{media_type};q=0.9"})
    for response in (by_accept, by_parameter, by_form):
        assert response.status_code == 200, response.text
        assert response.headers["content-type"].split(";")[0] == media_type
        assert read_rows(response.content) == published.name_rows()


def test_select_defaults_to_json_and_construct_to_turtle(published: Published) -> None:
    select = sparql(published.server, NAMES, accept="*/*")
    assert select.headers["content-type"] == "application/sparql-results+json"
    assert json_rows(select.content) == published.name_rows()
    construct = sparql(published.server, NAME_TRIPLES)
    assert construct.headers["content-type"] == "text/turtle; charset=utf-8"
    assert triples(construct) == published.name_triples()


@pytest.mark.parametrize(("name", "media_type"), GRAPH_FORMATS, ids=[f[0] for f in GRAPH_FORMATS])
def test_every_graph_format_parses_to_the_same_triples(published: Published, name: str, media_type: str) -> None:
    for response in (
        sparql(published.server, NAME_TRIPLES, accept=media_type),
        sparql(published.server, NAME_TRIPLES, format=name),
    ):
        assert response.status_code == 200, response.text
        assert response.headers["content-type"].split(";")[0] == media_type
        assert triples(response) == published.name_triples()


def test_describe_tells_about_a_resource(published: Published) -> None:
    response = sparql(published.server, f"DESCRIBE <{published.iri('maria')}>", accept="application/n-triples")
    assert response.status_code == 200, response.text
    maria = NamedNode(published.iri("maria"))
    assert Triple(maria, NamedNode(FOAF + "firstName"), Literal("Maria", language="en")) in triples(response)


def test_ask_answers_true_and_false_in_json_and_xml(published: Published) -> None:
    known = f"ASK {{ <{published.iri('maria')}> ?p ?o }}"
    unknown = "ASK { ?s ?p 'nobody said this' }"
    for query, expected in ((known, True), (unknown, False)):
        as_json = sparql(published.server, query)
        assert as_json.status_code == 200, as_json.text
        assert json.loads(as_json.content)["boolean"] is expected
        as_xml = sparql(published.server, query, accept="application/sparql-results+xml")
        assert ElementTree.fromstring(as_xml.content).find("r:boolean", RESULTS_NS).text == str(expected).lower()  # type: ignore[union-attr]


# --- what is refused --------------------------------------------------------------------------------------

FORBIDDEN = [
    ("INSERT DATA {<a:x> <a:y> <a:z>}", "update", "SPARQL Update (INSERT) is not allowed"),
    ("DELETE WHERE {?s ?p ?o}", "update", "SPARQL Update (DELETE) is not allowed"),
    ("prefix x: <http://x/> insert data { x:a x:b x:c }", "update", "SPARQL Update (INSERT) is not allowed"),
    ("LOAD <http://example.org/>", "update", "SPARQL Update (LOAD) is not allowed"),
    ("CLEAR ALL", "update", "SPARQL Update (CLEAR) is not allowed"),
    ("select * where { SERVICE <http://example.org/sparql> { ?s ?p ?o } }", "service", "SERVICE clauses"),
    ("select (bif:sprintf('%s','x') as ?x) {}", "virtuoso_extension", "Virtuoso extensions are not allowed"),
    ("SELECT * { ?s ?p ?o . ?o bif:contains 'Maria' }", "virtuoso_extension", "Virtuoso extensions"),
    ("define input:default-graph-uri <http://x> select * {?s ?p ?o}", "virtuoso_pragma", "DEFINE pragmas"),
    ("define sql:signal-void-variables 1 select * {?s ?p ?o}", "virtuoso_pragma", "DEFINE pragmas"),
    ("SELECT * FROM <http://ex.org/other> { ?s ?p ?o }", "dataset", "FROM <http://ex.org/other> is not allowed"),
    ("SELECT * { GRAPH ?g { ?s ?p ?o } }", "graph", "GRAPH patterns are not supported"),
]


def test_forbidden_queries_are_refused_naming_the_reason_and_change_nothing(published: Published) -> None:
    before = published.store.count()
    assert before > 300
    for query, reason, fragment in FORBIDDEN:
        # The standard endpoint answers the protocol's 400; the reference's /query its own 422.
        for status, response in (
            (400, sparql(published.server, query)),
            (400, published.post("/sparql", data={"query": query})),
            (
                400,
                published.post(
                    "/sparql",
                    content=query.encode(),
                    headers={"Content-Type": "application/sparql-query"},
                ),
            ),
            (422, published.get("/query", params={"query": query})),
        ):
            assert response.status_code == status, (query, response.text)
            body = response.json()
            assert (body["error"], body["reason"]) == ("invalid_query", reason), query
            assert fragment in body["detail"], body["detail"]
    # The SPARQL Update binding of the protocol (an `update` form field) is refused the same way.
    response = published.post("/sparql", data={"update": "DELETE WHERE {?s ?p ?o}"})
    assert (response.status_code, response.json()["reason"]) == (400, "update")
    assert published.store.count() == before
    assert json_rows(sparql(published.server, NAMES).content) == published.name_rows()


def test_a_syntax_error_answers_its_line_and_column(published: Published) -> None:
    query = f"PREFIX foaf: <{FOAF}>\nSELECT ?name WHERE {{\n  ?h foaf:firstName ?name .\n  FILTER(?name = )\n}}"
    response = sparql(published.server, query)
    assert response.status_code == 400
    body = response.json()
    assert (body["reason"], body["line"], body["column"]) == ("syntax", 4, 3)
    assert body["detail"] == "Invalid SPARQL syntax at line 4, column 3: unexpected 'FILTER'."


def test_the_dataset_is_the_events_graph_only(published: Published) -> None:
    graph = published.store.graph_uri
    same = [
        sparql(published.server, NAMES.replace("WHERE", f"FROM <{graph}> WHERE")),
        sparql(published.server, NAMES, **{"default-graph-uri": graph}),
    ]
    for response in same:
        assert response.status_code == 200, response.text
        assert json_rows(response.content) == published.name_rows()
    for params in ({"default-graph-uri": "http://ex.org/other"}, {"named-graph-uri": graph}):
        response = sparql(published.server, NAMES, **params)
        assert (response.status_code, response.json()["reason"]) == (400, "dataset")


# --- protocol details (store-independent) -----------------------------------------------------------------


def test_negotiation_failures_and_preferences(memory_api: InProcess) -> None:
    url = memory_api.client
    assert sparql(url, NAMES, accept="text/html").status_code == 406
    assert sparql(url, NAMES, format="turtle").status_code == 406
    assert sparql(url, NAME_TRIPLES, accept="text/csv").status_code == 406
    # `format` is a hint, read the way stock clients send it: an unknown value leaves the choice to Accept.
    bogus = sparql(url, NAMES, accept="text/csv", format="yaml")
    assert (bogus.status_code, bogus.headers["content-type"]) == (200, "text/csv; charset=utf-8")
    preferred = sparql(url, NAMES, accept="text/csv;q=0.5, application/sparql-results+xml, text/html")
    assert preferred.headers["content-type"] == "application/sparql-results+xml"
    assert sparql(url, NAMES, accept="text/*").headers["content-type"] == "text/csv; charset=utf-8"
    assert sparql(url, NAMES, accept="application/json").headers["content-type"] == "application/sparql-results+json"
    assert sparql(url, NAME_TRIPLES, accept="application/*").headers["content-type"] == "application/n-triples"
    assert sparql(url, NAMES).headers["vary"] == "Accept"


def test_format_hints_as_sparqlwrapper_sends_them(memory_api: InProcess) -> None:
    url = memory_api.client

    def get(query: str, *formats: str) -> httpx.Response:
        params = [("query", query), *(("format", value) for value in formats)]
        return http(url, "GET", "/sparql", params=params)

    agreeing = get(NAMES, "tsv", "text/tab-separated-values")
    assert agreeing.headers["content-type"] == "text/tab-separated-values; charset=utf-8"
    listed = get(NAME_TRIPLES, "json-ld", "application/ld+json,application/x-json+ld")
    assert listed.headers["content-type"] == "application/ld+json"
    assert get(NAME_TRIPLES, "xml").headers["content-type"] == "application/rdf+xml"  # RDF/XML for a graph
    assert get(NAMES, "xml").headers["content-type"] == "application/sparql-results+xml"
    assert get(NAME_TRIPLES, "n3").headers["content-type"] == "text/n3; charset=utf-8"
    disagreeing = get(NAMES, "json", "csv")
    assert (disagreeing.status_code, disagreeing.json()["parameter"]) == (422, "format")
    two_queries = http(url, "GET", "/sparql", params=[("query", NAMES), ("query", NAMES)])
    assert (two_queries.status_code, two_queries.json()["reason"]) == (400, "multiple_queries")


def test_bad_requests(memory_api: InProcess) -> None:
    url = memory_api.client
    missing = http(url, "GET", "/sparql")
    assert (missing.status_code, missing.json()["reason"]) == (400, "empty")
    wrong_type = http(url, "POST", "/sparql", content=NAMES.encode(), headers={"Content-Type": "text/plain"})
    assert wrong_type.status_code == 415
    too_long = "SELECT * { ?s ?p ?o }" + "#" * MAX_QUERY_BYTES
    response = http(
        url, "POST", "/sparql", content=too_long.encode(), headers={"Content-Type": "application/sparql-query"}
    )
    assert (response.status_code, response.json()["reason"]) == (413, "too_long")
    only_comments = http(
        url, "POST", "/sparql", content=b"# who spoke to ARI?\n", headers={"Content-Type": "application/sparql-query"}
    )
    assert (only_comments.status_code, only_comments.json()["reason"]) == (400, "empty")
    assert only_comments.json()["detail"].startswith("The query is empty")  # not "SPARQL Update is not allowed"


def test_only_auditors_and_admins_may_query(memory_store: Store) -> None:
    secret = "s" * 32
    with InProcess(create_app(make_settings(secret_key=secret), store=memory_store)) as server:
        assert sparql(server.client, NAMES).status_code == 401
        for roles, status in ((["logger"], 403), (["auditor"], 200), (["admin"], 200)):
            token = mint_token(secret, username="someone", roles=roles).token
            response = server.get("/sparql", params={"query": NAMES}, headers={"Authorization": f"Bearer {token}"})
            assert response.status_code == status, roles


# --- the reference backend's /query and /query/validate ---------------------------------------------------


def result_rows(turtle: bytes) -> list[dict[str, object]]:
    """Read /query's Turtle the way the reference web UI does: one row per ex:Result subject, in document
    order, values keyed by the predicate's local name."""
    rows: dict[object, dict[str, object]] = {}
    for quad in parse(turtle, RdfFormat.TURTLE):
        row = rows.setdefault(quad.subject, {})
        if quad.predicate.value != "http://www.w3.org/1999/02/22-rdf-syntax-ns#type":
            row[quad.predicate.value.removeprefix(EX)] = quad.object
        else:
            assert quad.object == NamedNode(EX + "Result")
    assert all(isinstance(subject, BlankNode) for subject in rows)
    return list(rows.values())


def test_reference_query_encodes_rows_as_turtle_in_order(published: Published) -> None:
    response = published.get("/query", params={"query": NAMES})
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "text/turtle; charset=utf-8"
    assert result_rows(response.content) == [
        {"human": NamedNode(iri), "name": Literal(name, language="en")} for iri, name in published.name_rows()
    ]
    ask = published.get("/query", params={"query": f"ASK {{ <{published.iri('juan')}> ?p ?o }}"})
    assert result_rows(ask.content) == [{"boolean": Literal(True)}]
    construct = published.get("/query", params={"query": NAME_TRIPLES})
    assert triples(construct) == published.name_triples()
    assert published.get("/query").status_code == 422  # the reference's answer to a missing query


def validate(server: Server, query: str) -> dict[str, object]:
    response = http(server, "POST", "/query/validate", json={"query": query})
    assert response.status_code == 200, response.text
    return response.json()


def test_reference_validate_reports_without_running(memory_api: InProcess) -> None:
    url = memory_api.client
    assert validate(url, NAMES) == {
        "valid": True,
        "query_kind": "select",
        "form": "select",
        "allows_update_execution": False,
        "message": "Valid SPARQL query.",
        "error": None,
        "reason": None,
        "line": None,
        "column": None,
    }
    update = validate(url, "prefix x: <http://x/> insert data { x:a x:b x:c }")
    assert (update["valid"], update["query_kind"], update["reason"]) == (False, "update", "update")
    assert update["message"] == update["error"]
    assert str(update["message"]).startswith("SPARQL Update (INSERT) is not allowed")
    syntax = validate(url, "SELECT ?s WHERE {\n  ?s ?p\n}")
    assert (syntax["valid"], syntax["reason"], syntax["line"], syntax["column"]) == (False, "syntax", 2, 3)
    service = validate(url, "SELECT * { SERVICE <http://example.org/sparql> { ?s ?p ?o } }")
    assert (service["valid"], service["query_kind"], service["reason"]) == (False, "select", "service")
    unknown = validate(url, "HELLO WORLD")
    assert (unknown["valid"], unknown["query_kind"], unknown["form"]) == (False, "unknown", None)
    for form in ("ask", "construct", "describe"):
        query = {"ask": "ASK {}", "construct": "CONSTRUCT WHERE { ?s ?p ?o }", "describe": "DESCRIBE <http://x.org/>"}
        assert validate(url, query[form])["query_kind"] == form
    assert http(url, "POST", "/query/validate", json={}).status_code == 422
