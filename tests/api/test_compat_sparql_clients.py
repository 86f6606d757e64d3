"""Stock SPARQL clients against /sparql, unchanged, over real HTTP: SPARQLWrapper 2.x with its defaults and with
every return format over GET, POST form and POST direct (`.convert()` included), rdflib's SPARQLStore through a
Graph, a ConjunctiveGraph and a Dataset, and the protocol's refusal of two queries on every method."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from xml.dom.minidom import Document

import httpx
import pytest
from rdflib import Dataset, Graph, Literal, URIRef
from rdflib.graph import ConjunctiveGraph
from rdflib.plugins.stores.sparqlstore import SPARQLStore
from SPARQLWrapper import (
    CSV,
    GET,
    JSON,
    JSONLD,
    N3,
    POST,
    POSTDIRECTLY,
    RDFXML,
    TSV,
    TURTLE,
    URLENCODED,
    XML,
    SPARQLWrapper,
)

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby

FOAF = "http://xmlns.com/foaf/0.1/"
NAMES = f"PREFIX foaf: <{FOAF}>\nSELECT ?human ?name WHERE {{ ?human foaf:firstName ?name }} ORDER BY ?name"
NAME_TRIPLES = f"PREFIX foaf: <{FOAF}>\nCONSTRUCT {{ ?h foaf:firstName ?n }} WHERE {{ ?h foaf:firstName ?n }}"
GRAPH_URI = "http://amor-segb/events"


class Published:
    """A server holding the lobby scenario, published by the PyPI client, and what NAMES and NAME_TRIPLES
    must answer on it."""

    def __init__(self, url: str) -> None:
        scenario = lobby()
        scenario.publish_all(url)
        self.url = url
        self.endpoint = f"{url}/sparql"
        people = [(str(scenario.iris["juan"]), "Juan"), (str(scenario.iris["maria"]), "Maria")]
        self.rows = people
        self.triples = {(URIRef(iri), URIRef(FOAF + "firstName"), Literal(name, lang="en")) for iri, name in people}


@pytest.fixture(scope="module")
def published() -> Iterator[Published]:
    store = OxigraphStore(GRAPH_URI)
    with LiveServer(create_app(make_settings(), store=store)) as server:
        yield Published(server.url)
    store.close()


# --- SPARQLWrapper --------------------------------------------------------------------------------------------

METHODS = {"GET": (GET, URLENCODED), "POST form": (POST, URLENCODED), "POST direct": (POST, POSTDIRECTLY)}
# return format (None: SPARQLWrapper's default, XML) → the media type the server answers
SELECT_FORMATS = {
    None: "application/sparql-results+xml",
    JSON: "application/sparql-results+json",
    XML: "application/sparql-results+xml",
    CSV: "text/csv",
    TSV: "text/tab-separated-values",
}
CONSTRUCT_FORMATS = {
    None: "application/rdf+xml",
    XML: "application/rdf+xml",
    RDFXML: "application/rdf+xml",
    TURTLE: "text/turtle",
    JSONLD: "application/ld+json",
    N3: "text/n3",
    JSON: "application/ld+json",  # SPARQLWrapper's `format=json` for a graph: JSON-LD
}


def run(endpoint: str, query: str, method: str, return_format: str | None) -> tuple[str, object]:
    client = SPARQLWrapper(endpoint)
    client.setQuery(query)
    http_method, request_method = METHODS[method]
    client.setMethod(http_method)
    client.setRequestMethod(request_method)
    if return_format is not None:
        client.setReturnFormat(return_format)
    result = client.query()
    media_type = result.response.headers["content-type"].split(";")[0]
    return media_type, result.convert()


def rows_of(converted: object) -> list[tuple[str, str]]:
    """The (human, name) rows of a converted SELECT answer, whatever its format."""
    if isinstance(converted, dict):  # SPARQL JSON
        return [(row["human"]["value"], row["name"]["value"]) for row in converted["results"]["bindings"]]
    if isinstance(converted, Document):  # SPARQL XML, as a DOM
        rows = []
        for result in converted.getElementsByTagName("result"):
            values = {
                binding.getAttribute("name"): binding.firstChild.firstChild.data
                for binding in result.getElementsByTagName("binding")
            }
            rows.append((values["human"], values["name"]))
        return rows
    assert isinstance(converted, bytes)
    text = converted.decode()
    if "\t" in text:  # TSV: terms in Turtle syntax
        lines = [line.split("\t") for line in text.splitlines()[1:] if line]
        return [(human.strip("<>"), name.split('"')[1]) for human, name in lines]
    return [(human, name) for human, name in list(csv.reader(io.StringIO(text)))[1:]]


def triples_of(converted: object, media_type: str) -> set[tuple[object, object, object]]:
    """The triples of a converted CONSTRUCT answer: a graph already, or text for rdflib to read."""
    if isinstance(converted, Graph):
        return set(converted)
    assert isinstance(converted, bytes)
    return set(Graph().parse(data=converted, format={"text/turtle": "turtle", "text/n3": "n3"}[media_type]))


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("return_format", list(SELECT_FORMATS), ids=lambda f: f or "default")
def test_sparqlwrapper_select_in_every_result_format(published: Published, method: str, return_format: str) -> None:
    media_type, converted = run(published.endpoint, NAMES, method, return_format)
    assert media_type == SELECT_FORMATS[return_format]
    assert rows_of(converted) == published.rows


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("return_format", list(CONSTRUCT_FORMATS), ids=lambda f: f or "default")
def test_sparqlwrapper_construct_in_every_graph_format(published: Published, method: str, return_format: str) -> None:
    media_type, converted = run(published.endpoint, NAME_TRIPLES, method, return_format)
    assert media_type == CONSTRUCT_FORMATS[return_format]
    assert triples_of(converted, media_type) == published.triples


def test_sparqlwrapper_ask_and_describe(published: Published) -> None:
    for method in METHODS:
        media_type, dom = run(published.endpoint, "ASK { ?s ?p ?o }", method, None)
        assert media_type == "application/sparql-results+xml" and isinstance(dom, Document)
        assert dom.getElementsByTagName("boolean")[0].firstChild.data == "true"
        assert run(published.endpoint, "ASK { <urn:nothing> ?p ?o }", method, JSON)[1]["boolean"] is False
        media_type, described = run(published.endpoint, f"DESCRIBE <{published.rows[0][0]}>", method, None)
        assert media_type == "application/rdf+xml" and isinstance(described, Graph)
        assert (URIRef(published.rows[0][0]), URIRef(FOAF + "firstName"), Literal("Juan", lang="en")) in described


@pytest.fixture
def api(store: Store) -> Iterator[LiveServer]:
    """The API over real HTTP, on each store: SPARQLWrapper and the other clients bring their own HTTP."""
    with LiveServer(create_app(make_settings(), store=store)) as server:
        yield server


def test_sparqlwrapper_defaults_on_each_store(api: LiveServer) -> None:
    """The same answers from the embedded store and from a real Virtuoso."""
    published = Published(api.url)
    for method in METHODS:
        assert rows_of(run(published.endpoint, NAMES, method, None)[1]) == published.rows
        media_type, graph = run(published.endpoint, NAME_TRIPLES, method, None)
        assert triples_of(graph, media_type) == published.triples


# --- rdflib's SPARQLStore ----------------------------------------------------------------------------------


def sparql_store(published: Published, **options: str) -> SPARQLStore:
    return SPARQLStore(published.endpoint, **options)


STORE_OPTIONS = {
    "defaults": {},
    "POST": {"method": "POST"},
    "POST_FORM": {"method": "POST_FORM"},
    "json": {"returnFormat": "json"},
}


@pytest.mark.parametrize("options", sorted(STORE_OPTIONS))
@pytest.mark.parametrize("kind", ["Graph", "Graph of the events graph", "ConjunctiveGraph", "Dataset"])
def test_rdflib_sparqlstore_reads_the_events_graph(published: Published, options: str, kind: str) -> None:
    store = sparql_store(published, **STORE_OPTIONS[options])
    graph: Graph = {
        "Graph": lambda: Graph(store=store),
        "Graph of the events graph": lambda: Graph(store=store, identifier=URIRef(GRAPH_URI)),  # default-graph-uri
        "ConjunctiveGraph": lambda: ConjunctiveGraph(store=store),
        # A Dataset names the default graph urn:x-rdflib:default in its requests.
        "Dataset": lambda: Dataset(store=store),
    }[kind]()
    rows = [(str(row[0]), str(row[1])) for row in graph.query(NAMES)]
    assert rows == published.rows
    assert graph.query("ASK { ?s ?p ?o }").askAnswer is True
    first_name = URIRef(FOAF + "firstName")
    assert {triple for triple in graph.triples((None, first_name, None))} == published.triples
    assert len(graph) > 100
    if options != "json":  # a graph is not SPARQL JSON: see the next test
        assert set(graph.query(NAME_TRIPLES)) == published.triples


def test_rdflib_sparqlstore_asking_json_for_a_graph_gets_406(published: Published) -> None:
    """rdflib's returnFormat="json" accepts only SPARQL JSON, which a CONSTRUCT cannot be; the server says so
    with 406 rather than send a format the client did not accept (rdflib's default, XML, accepts RDF/XML)."""
    answer = httpx.get(
        published.endpoint, params={"query": NAME_TRIPLES}, headers={"Accept": "application/sparql-results+json"}
    )
    assert answer.status_code == 406
    with pytest.raises(ValueError):
        Graph(store=sparql_store(published, returnFormat="json")).query(NAME_TRIPLES)


def test_dataset_parameters_naming_another_graph_are_still_refused(published: Published) -> None:
    for graph in ("http://example.org/other", "urn:x-rdflib:other"):
        answer = httpx.get(published.endpoint, params={"query": "ASK {}", "default-graph-uri": graph})
        assert (answer.status_code, answer.json()["reason"]) == (400, "dataset"), graph


# --- two queries: the W3C protocol test bad_multiple_queries, on every method ---------------------------------

TWO_QUERIES = {
    "GET": {"method": "GET", "params": [("query", "ASK {}"), ("query", "ASK { ?s ?p ?o }")]},
    "POST form": {
        "method": "POST",
        "content": "query=ASK+%7B%7D&query=ASK+%7B+%3Fs+%3Fp+%3Fo+%7D",
        "headers": {"Content-Type": "application/x-www-form-urlencoded"},
    },
    "POST form and query string": {
        "method": "POST",
        "params": {"query": "ASK {}"},
        "content": "query=ASK+%7B%7D",
        "headers": {"Content-Type": "application/x-www-form-urlencoded"},
    },
    "POST direct and query string": {
        "method": "POST",
        "params": {"query": "ASK {}"},
        "content": "ASK {}",
        "headers": {"Content-Type": "application/sparql-query"},
    },
}


@pytest.mark.parametrize("name", sorted(TWO_QUERIES))
def test_two_queries_are_refused_with_400_on_every_method(published: Published, name: str) -> None:
    request = dict(TWO_QUERIES[name])
    answer = httpx.request(str(request.pop("method")), published.endpoint, **request)
    assert answer.status_code == 400, answer.text
    assert (answer.json()["error"], answer.json()["reason"]) == ("invalid_query", "multiple_queries")


def test_a_direct_post_keeps_its_other_query_string_parameters(published: Published) -> None:
    answer = httpx.post(
        published.endpoint,
        params={"format": "csv", "default-graph-uri": GRAPH_URI},
        content=NAMES,
        headers={"Content-Type": "application/sparql-query"},
    )
    assert (answer.status_code, answer.headers["content-type"]) == (200, "text/csv; charset=utf-8")
