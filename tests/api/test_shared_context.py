"""/shared-context: the PyPI client's resolver over real HTTP; review decisions, persistence and concurrency through
the whole app in process."""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import httpx
import pytest
from rdflib import URIRef
from semantic_log_generator import SemanticSEGBLogger
from semantic_log_generator.shared_context import HTTPSharedContextResolver

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.in_process import InProcess, publisher_for
from tests.support.live_server import LiveServer

NAMESPACE = "https://gsi.upm.es/segb/shared-events/"
MARIA = "https://example.org/people/maria"
AT = datetime(2026, 5, 4, 10, 0, 0, tzinfo=UTC)


def utterance(seconds: float, subject: str | None = MARIA, text: str = "Good morning, robot!") -> dict[str, Any]:
    return {
        "event_kind": "human_utterance",
        "observed_at": (AT + timedelta(seconds=seconds)).isoformat(),
        "subject_uri": subject,
        "modality": "speech",
        "text": text,
    }


def resolve(server: InProcess | LiveServer, body: dict[str, Any]) -> dict[str, Any]:
    answer = server.post("/shared-context/resolve", json=body)
    assert answer.status_code == 200, answer.text
    return answer.json()


def get(server: InProcess | LiveServer, path: str) -> dict[str, Any]:
    answer = server.get(path)
    assert answer.status_code == 200, answer.text
    return answer.json()


def post(server: InProcess, path: str, body: dict[str, Any] | None = None) -> httpx.Response:
    return server.post(path, json=body or {})


@pytest.fixture
def on_disk(tmp_path: Path) -> Iterator[InProcess]:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        yield server


def robot(robot_id: str, server: LiveServer) -> SemanticSEGBLogger:
    """A robot asking `server` for shared events with the client's own resolver (requests, so a real socket)."""
    return SemanticSEGBLogger(
        base_namespace=f"https://example.org/robots/{robot_id}/",
        robot_id=robot_id,
        shared_event_resolver=HTTPSharedContextResolver(base_url=server.url, raise_on_error=True),
    )


def test_two_robots_with_the_pypi_resolver_log_one_shared_event(live_api: LiveServer) -> None:
    ari, tiago = robot("ari", live_api), robot("tiago", live_api)
    seen_by_ari = ari.get_shared_event_uri(
        event_kind="human_utterance", observed_at=AT, subject=URIRef(MARIA), text="Hello there", modality="speech"
    )
    seen_by_tiago = tiago.get_shared_event_uri(
        event_kind="human_utterance",
        observed_at=AT + timedelta(milliseconds=800),
        subject=URIRef(MARIA),
        text="hello there!",
        modality="speech",
    )
    assert seen_by_ari == seen_by_tiago
    assert str(seen_by_ari).startswith(NAMESPACE + "human_utterance_")

    for name, logger in (("ari", ari), ("tiago", tiago)):
        publisher_for(live_api.url).publish_graph(logger.graph, user=name)
    asked = live_api.get(
        "/sparql", params={"query": f"SELECT (COUNT(*) AS ?n) WHERE {{ <{seen_by_ari}> ?p ?o }}"}
    ).json()
    assert int(asked["results"]["bindings"][0]["n"]["value"]) > 0

    stats = get(live_api, "/shared-context/stats")
    assert (stats["active_contexts"], stats["ambiguous_contexts"]) == (1, 0)


def test_created_then_matched_then_ambiguous_with_the_reference_scores(memory_api: InProcess) -> None:
    first = resolve(memory_api, utterance(0))
    assert (first["status"], first["candidate_count"]) == ("created", 0)

    second = resolve(memory_api, utterance(0.8))
    assert second["status"] == "matched"
    assert second["shared_context_uri"] == first["shared_context_uri"]
    assert second["confidence"] == pytest.approx(0.916, abs=0.001)

    other_person = resolve(memory_api, utterance(0.9, subject="https://example.org/people/juan", text="Where to?"))
    assert other_person["status"] == "created"  # a different subject is never the same event

    # Half a second after the (sliding) anchor, without a subject: 0.842, between the two thresholds.
    third = resolve(memory_api, utterance(1.3, subject=None))
    assert third["status"] == "ambiguous"
    assert third["confidence"] == pytest.approx(0.842, abs=0.001)
    assert third["shared_context_uri"] != first["shared_context_uri"]
    assert third["close_candidates"] == [first["shared_context_uri"], other_person["shared_context_uri"]]


def test_accepting_a_review_merges_the_ambiguous_context(memory_api: InProcess) -> None:
    target = resolve(memory_api, utterance(0))["shared_context_uri"]
    source = resolve(memory_api, utterance(0.5, subject=None))["shared_context_uri"]

    queue = get(memory_api, "/shared-context/review/pending")
    assert (queue["unresolved_count"], queue["pending_count"]) == (1, 1)
    case = queue["pending_cases"][0]
    assert case["source_context_uri"] == source
    assert [candidate["context_uri"] for candidate in case["candidates"]] == [target]
    assert {context["uri"] for context in queue["contexts"]} == {source, target}

    not_a_candidate = post(
        memory_api, f"/shared-context/review/{case['case_id']}/accept", {"target_context_uri": source}
    )
    assert not_a_candidate.status_code == 422
    assert "target_context_uri" in not_a_candidate.json()["detail"]

    accepted = post(memory_api, f"/shared-context/review/{case['case_id']}/accept", {"target_context_uri": target})
    assert accepted.status_code == 200, accepted.text
    assert accepted.json()["resulting_context_uri"] == target

    assert get(memory_api, "/shared-context/review/pending")["pending_count"] == 0
    stats = get(memory_api, "/shared-context/stats")
    assert (stats["active_contexts"], stats["ambiguous_contexts"], stats["merged_contexts"], stats["aliases"]) == (
        1,
        0,
        1,
        1,
    )
    again = post(memory_api, f"/shared-context/review/{case['case_id']}/accept", {"target_context_uri": target})
    assert again.status_code == 422  # as the reference answers an already decided case
    assert post(memory_api, "/shared-context/review/review_000000000000/reject").status_code == 422

    # A later observation of the same event resolves to the surviving context.
    assert resolve(memory_api, utterance(1.0))["shared_context_uri"] == target


def test_rejecting_keeps_the_context_apart_and_never_proposes_the_pair_again(memory_api: InProcess) -> None:
    resolve(memory_api, utterance(0))
    source = resolve(memory_api, utterance(0.5, subject=None))["shared_context_uri"]
    case = get(memory_api, "/shared-context/review/pending")["pending_cases"][0]

    rejected = post(memory_api, f"/shared-context/review/{case['case_id']}/reject")
    assert rejected.status_code == 200, rejected.text
    assert rejected.json()["status"] == "rejected"

    reconciled = post(memory_api, "/shared-context/reconcile").json()
    assert (reconciled["merged_count"], reconciled["pending_cases"]) == (0, 0)
    queue = get(memory_api, "/shared-context/review/pending")
    assert [context["uri"] for context in queue["unresolved_contexts"]] == [source]
    assert queue["pending_cases"] == []


def test_reading_the_review_queue_changes_nothing(memory_api: InProcess) -> None:
    resolve(memory_api, utterance(0))
    resolve(memory_api, utterance(0.5, subject=None))
    before = (get(memory_api, "/shared-context/stats"), get(memory_api, "/shared-context/review/pending"))
    for _ in range(3):
        get(memory_api, "/shared-context/review/pending")
    assert (get(memory_api, "/shared-context/stats"), get(memory_api, "/shared-context/review/pending")) == before


def test_the_state_survives_a_restart_and_uris_are_deterministic(tmp_path: Path) -> None:
    def first_two(server: InProcess) -> list[str]:
        return [resolve(server, utterance(0))["shared_context_uri"], resolve(server, utterance(0.5, None))["status"]]

    settings = make_settings(store="oxigraph", data_dir=tmp_path / "one")
    with InProcess(create_app(settings)) as server:
        created, status = first_two(server)
        assert status == "ambiguous"
    with InProcess(create_app(settings)) as restarted:
        assert get(restarted, "/shared-context/review/pending")["pending_count"] == 1
        matched = resolve(restarted, utterance(0.7))
        assert (matched["status"], matched["shared_context_uri"]) == ("matched", created)

    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path / "two"))) as elsewhere:
        assert first_two(elsewhere) == [created, "ambiguous"]


def test_robots_resolving_the_same_event_at_once_get_one_context(on_disk: InProcess) -> None:
    bodies = [utterance(index * 0.05) for index in range(16)]
    with ThreadPoolExecutor(max_workers=16) as pool:
        answers = list(pool.map(lambda body: resolve(on_disk, body), bodies))
    assert len({answer["shared_context_uri"] for answer in answers}) == 1
    assert sorted(answer["status"] for answer in answers) == ["created"] + ["matched"] * 15
    stats = get(on_disk, "/shared-context/stats")
    assert (stats["active_contexts"], stats["ambiguous_contexts"]) == (1, 0)


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"event_kind": "  "}, "event_kind"),
        ({"observed_at": "yesterday"}, "observed_at"),
        ({"text": "x" * 5000}, "text"),
        ({"time_window_seconds": -1}, "time_window_seconds"),
        ({"time_window_seconds": "nan"}, "finite number"),
        ({"subject_uri": "not an iri <script>"}, "subject_uri"),
        ({"robot_uri": "javascript:alert(13)"}, "robot_uri"),
        ({"observation_uri": "https://example.org/a b"}, "observation_uri"),
    ],
)
def test_bad_requests_are_refused_naming_the_field(memory_api: InProcess, change: dict[str, Any], named: str) -> None:
    answer = post(memory_api, "/shared-context/resolve", {**utterance(0), **change})
    assert answer.status_code == 422
    assert named in answer.text
    assert get(memory_api, "/shared-context/stats")["active_contexts"] == 0
