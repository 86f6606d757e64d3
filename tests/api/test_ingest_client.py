"""The PyPI client `semantic-log-generator` 1.0.5, unchanged, publishing into the server over real HTTP: its own
transport (requests) against uvicorn, on both stores. Elsewhere the tests serve the API in process."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest
import requests
from pyoxigraph import RdfFormat
from semantic_log_generator import SEGBPublisher

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store
from tests.conftest import FIXTURES, make_settings
from tests.support.graphs import triples, value_triples
from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby


@pytest.fixture
def api(store: Store) -> Iterator[LiveServer]:
    """The API over real HTTP, on each store (this module's tests are about the client's own transport)."""
    with LiveServer(create_app(make_settings(), store=store)) as server:
        yield server


def stored_graph(server: LiveServer) -> bytes:
    response = httpx.get(f"{server.url}/events", headers={"Accept": "application/n-triples"}, timeout=60)
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("application/n-triples")
    return response.content


def test_cumulative_publishing_stores_exactly_the_clients_graph(api: LiveServer, store: Store) -> None:
    scenario = lobby()
    responses = scenario.publish_all(api.url)

    assert len(responses) == len(scenario.steps)
    assert all(response["triples_new"] <= response["triples_received"] for response in responses)
    expected = set().union(*(value_triples(ttl, RdfFormat.TURTLE) for ttl in scenario.published_turtle()))
    assert value_triples(stored_graph(api)) == expected
    assert store.count() == len(expected)


def test_republishing_the_whole_graph_adds_nothing(api: LiveServer, store: Store) -> None:
    scenario = lobby()
    scenario.run_steps()
    publisher = SEGBPublisher(base_url=api.url)
    ari = scenario.loggers["ari"]

    first = ari.publish(publisher)
    again = ari.publish(publisher)

    assert first["triples_new"] == first["triples_received"] == len(ari.graph)
    assert again["triples_received"] == len(ari.graph)
    assert again["triples_new"] == 0
    assert store.count() == len(ari.graph)


def test_each_cumulative_post_reports_only_the_delta_as_new(api: LiveServer) -> None:
    scenario = lobby()
    seen: dict[str, int] = {}
    expected_new = []

    def note(robot: str) -> None:
        graph = scenario.loggers[robot].graph
        expected_new.append(len(graph) - seen.get(robot, 0))
        seen[robot] = len(graph)

    publishers = {name: SEGBPublisher(base_url=api.url) for name in scenario.loggers}
    reported = []

    def publish_and_note(robot: str) -> None:
        note(robot)
        reported.append(scenario.loggers[robot].publish(publishers[robot])["triples_new"])

    scenario.run_steps(publish_and_note)
    # Both robots publish Juan's IRI in their graphs only as objects, so deltas never overlap across robots.
    assert reported == expected_new


def test_client_delete_all_clears_the_events_graph(api: LiveServer, store: Store) -> None:
    scenario = lobby()
    scenario.publish_all(api.url)
    assert store.count() > 0

    answer = SEGBPublisher(base_url=api.url).delete_all_ttls(user="ari")

    assert answer["message"] == "Graph cleared."
    assert answer["triples_removed"] > 0
    assert store.count() == 0
    assert triples(stored_graph(api)) == set()


def test_offline_queue_is_flushed_once_the_server_is_back(tmp_path, memory_store: Store) -> None:
    from segb_server.backend.api.app import create_app
    from tests.conftest import make_settings

    scenario = lobby()
    scenario.run_steps()
    ari = scenario.loggers["ari"]
    queue = tmp_path / "queue.jsonl"
    app = create_app(make_settings(), store=memory_store)
    with LiveServer(app) as server:
        url, port = server.url, server.port
    offline = SEGBPublisher(base_url=url, queue_file=str(queue), timeout_seconds=2)

    with pytest.raises(requests.ConnectionError):
        ari.publish(offline)
    assert queue.read_text().count("\n") == 1

    with LiveServer(create_app(make_settings(), store=memory_store), port=port):
        flushed = offline.flush_queue()

    assert [answer["triples_new"] for answer in flushed] == [len(ari.graph)]
    assert not queue.exists()
    assert memory_store.count() == len(ari.graph)


FIXTURE_FILES = ["sample_two_robots.ttl", "reference_uc01.ttl", "reference_uc02.ttl"]
EXPORT_SYNTAXES = [
    ("text/turtle", RdfFormat.TURTLE),
    ("application/n-triples", RdfFormat.N_TRIPLES),
    ("application/n-quads", RdfFormat.N_QUADS),
    ("application/ld+json", RdfFormat.JSON_LD),
]


@pytest.mark.parametrize("name", FIXTURE_FILES)
def test_fixtures_from_the_real_client_round_trip_through_events(api: LiveServer, store: Store, name: str) -> None:
    ttl = (FIXTURES / name).read_text(encoding="utf-8")
    answer = httpx.post(f"{api.url}/ttl", json={"ttl_content": ttl, "user": "fixture"}, timeout=60)
    assert answer.status_code == 201, answer.text
    expected = triples(ttl, RdfFormat.TURTLE)
    assert answer.json()["triples_new"] == len(expected)

    for media, rdf_format in EXPORT_SYNTAXES:
        exported = httpx.get(f"{api.url}/events", headers={"Accept": media}, timeout=60)
        assert exported.status_code == 200
        assert exported.headers["content-type"].startswith(media)
        assert value_triples(exported.content, rdf_format) == value_triples(ttl, RdfFormat.TURTLE), media


def test_nquads_export_names_the_events_graph(api: LiveServer, store: Store) -> None:
    httpx.post(f"{api.url}/ttl", json={"ttl_content": "<https://ex.org/a> <https://ex.org/p> 1 ."}, timeout=30)
    exported = httpx.get(f"{api.url}/events", params={"format": "nquads"}, timeout=30)
    assert exported.text.strip().endswith(f"<{store.graph_uri}> .")
