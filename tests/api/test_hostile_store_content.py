"""Whatever the store holds, every read path answers: an RDF 1.2 triple term written by someone else (an old
server, another writer of a shared store) must not break exports, queries, resources or explanations. New
posts with triple terms are refused, on every store."""

from __future__ import annotations

import json
from collections.abc import Iterator

import httpx
import pytest
from pyoxigraph import NamedNode, Quad, Triple

from segb_server.backend.api.app import create_app
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.in_process import InProcess
from tests.support.settle import settle

EX = "https://e.org/"
SAYS = f"<{EX}a> <{EX}says> <<( <{EX}s> <{EX}p> <{EX}o> )>> ."


def test_a_post_with_a_triple_term_is_refused_and_writes_nothing(api: InProcess) -> None:
    refused = api.post("/ttl", content=SAYS, headers={"Content-Type": "text/turtle"})
    assert refused.status_code == 400
    assert "triple terms" in refused.json()["detail"]
    assert "INSERT" not in refused.text and "amor-segb" not in refused.text  # nothing internal leaks
    count = api.get("/sparql", params={"query": "SELECT (COUNT(*) AS ?n) { ?s ?p ?o }"}).json()
    assert count["results"]["bindings"][0]["n"]["value"] == "0"


@pytest.fixture
def poisoned() -> Iterator[InProcess]:
    store = OxigraphStore("http://amor-segb/events")
    term = Triple(NamedNode(EX + "s"), NamedNode(EX + "p"), NamedNode(EX + "o"))
    store.apply([Quad(NamedNode(EX + "a"), NamedNode(EX + "says"), term)], 0)  # written by someone else
    with InProcess(create_app(make_settings(), store=store)) as server:
        yield server
    store.close()


@pytest.mark.parametrize("fmt", ["turtle", "ntriples", "nquads", "jsonld"])
def test_every_export_format_answers_whole(poisoned: InProcess, fmt: str) -> None:
    answer = poisoned.get("/events", params={"format": fmt})
    assert answer.status_code == 200
    if fmt == "jsonld":  # JSON-LD 1.1 cannot carry a triple term: the document stays valid JSON without it
        assert answer.json() == []
    else:
        assert f"<{EX}s>" in answer.text


@pytest.mark.parametrize("path", ["/sparql", "/query"])
def test_queries_over_a_triple_term_answer(poisoned: InProcess, path: str) -> None:
    answer = poisoned.get(path, params={"query": "SELECT * { ?s ?p ?o }"})
    assert answer.status_code == 200, answer.text
    assert f"{EX}s" in answer.text


@pytest.mark.parametrize("path", ["/resource", "/explain"])
def test_the_resource_and_its_explanation_answer(poisoned: InProcess, path: str) -> None:
    answer = poisoned.get(path, params={"iri": EX + "a"})
    assert answer.status_code in (200, 404), answer.text
    assert answer.headers["content-type"] == "application/json"


def emotion_timeline_with_intensity(server: InProcess, intensity: str) -> httpx.Response:
    """The emotion timeline after one reading of the given intensity (a Turtle literal) is posted."""
    turtle = f"""
        @prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> .
        @prefix onyx: <http://www.gsi.upm.es/ontologies/onyx/ns#> .
        @prefix oa: <http://www.w3.org/ns/oa#> . @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
        @prefix prov: <http://www.w3.org/ns/prov#> .
        <{EX}act> segb:producedEntityResult <{EX}ann> ; prov:startedAtTime "2026-01-01T00:00:00Z"^^xsd:dateTime .
        <{EX}ann> onyx:hasEmotion <{EX}emo> ; oa:hasTarget <{EX}h> .
        <{EX}emo> onyx:hasEmotionCategory <{EX}joy> ; onyx:hasEmotionIntensity {intensity} .
    """
    posted = server.post("/ttl", content=turtle, headers={"Content-Type": "text/turtle"})
    assert posted.status_code == 201, posted.text
    settle(server.client)  # a report's rows follow the store a moment after the 201
    page = server.get("/reports/emotion-timeline")
    assert page.status_code == 200, page.text
    return page


def test_a_report_row_holding_an_integer_past_64_bits_answers(memory_api: InProcess) -> None:
    """JSON answers are encoded by orjson, which refuses integers past 64 bits; such a value (a robot may log
    any xsd:integer) must still reach the page whole."""
    huge = "123456789012345678901234567890"
    page = emotion_timeline_with_intensity(memory_api, f'"{huge}"^^xsd:integer')
    assert f'"intensity":{huge}' in page.text.replace(" ", "")


@pytest.mark.parametrize("odd", ["NaN", "INF", "-INF"])
def test_a_report_row_holding_a_double_json_cannot_write_answers_as_json(memory_api: InProcess, odd: str) -> None:
    """xsd:double has NaN and infinities, which JSON has no way to write: a page holding one is still JSON any
    strict reader takes, the value left out as null."""
    page = emotion_timeline_with_intensity(memory_api, f'"{odd}"^^xsd:double')

    def refuse(constant: str) -> None:
        raise AssertionError(f"not JSON: {constant}")

    rows = json.loads(page.text, parse_constant=refuse)["rows"]
    assert [row["intensity"] for row in rows] == [None]
