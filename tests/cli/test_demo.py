"""The demo dataset: `segb demo` publishes it to a running server, `segb serve --demo` loads it once."""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from segb_server.backend.api.app import create_app
from tests.cli.test_cli import SEGB, clean_env, segb, wait_for
from tests.conftest import make_settings
from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer
from tests.support.net import free_port
from tests.support.settle import settle
from tests.support.sparql import select_bindings

REPORTS = ["participants", "ml-usage", "emotion-timeline", "extreme-emotions", "conversations", "robot-states"]
# Shared events that activities of two different robots are about.
SHARED_BY_TWO_ROBOTS = """
PREFIX schema: <http://schema.org/>
PREFIX segb: <http://www.gsi.upm.es/ontologies/segb/ns#>
SELECT DISTINCT ?event WHERE {
  ?one schema:about ?event ; segb:wasPerformedBy ?first .
  ?other schema:about ?event ; segb:wasPerformedBy ?second .
  FILTER (?first != ?second)
}
"""


# An emotion read on a person, by an activity not linked to the shared event of the exchange, about that person,
# that the reading belongs to: what the reference UI's human-emotion panels need (reference-ui.md, report 3).
EMOTIONS_WITHOUT_THEIR_EVENT = """
PREFIX schema: <http://schema.org/>
PREFIX segb: <http://www.gsi.upm.es/ontologies/segb/ns#>
PREFIX onyx: <http://www.gsi.upm.es/ontologies/onyx/ns#>
PREFIX oa: <http://www.w3.org/ns/oa#>
PREFIX oro: <http://kb.openrobots.org#>
SELECT ?activity ?person WHERE {
  ?activity a onyx:EmotionAnalysis, segb:LoggedActivity ; segb:producedEntityResult ?annotation .
  ?annotation onyx:hasEmotion ?emotion ; oa:hasTarget ?person .
  ?person a oro:Human .
  FILTER NOT EXISTS { ?activity schema:about ?event . ?event schema:about ?person }
}
"""


def test_every_emotion_the_demo_reads_on_a_person_is_about_that_persons_shared_event(tmp_path: Path) -> None:
    """As the tutorial's robot logs it, a reading on a face is `schema:about` the shared event of the utterance it
    came with, and that event is about the person: the reference web UI shows such readings only."""
    with InProcess(create_app(make_settings(store="memory", data_dir=tmp_path), demo=True)) as api:
        settle(api.client)
        timeline = api.get("/reports/emotion-timeline").json()["rows"]
        unlinked = select_bindings(api.client, EMOTIONS_WITHOUT_THEIR_EVENT)
    assert {row["targetName"] for row in timeline if row["targetKind"] == "human"} == {"Maria", "Carlos"}
    assert unlinked == []


def rows(url: str, name: str) -> list[dict[str, Any]]:
    settle(url)  # the reports are rows kept current from the journal: read them once they include every post
    response = httpx.get(f"{url}/reports/{name}", timeout=30)
    assert response.status_code == 200, response.text
    return response.json()["rows"]


def triple_count(url: str) -> int:
    return len(httpx.get(f"{url}/events", params={"format": "ntriples"}, timeout=30).text.splitlines())


@pytest.mark.processes
def test_segb_demo_fills_every_report_once(live_api: LiveServer) -> None:
    published = segb("demo", "--server", live_api.url)
    assert published.returncode == 0, published.stderr
    assert "demo dataset published" in published.stdout

    for name in REPORTS:
        assert rows(live_api.url, name), f"{name} has no rows"
    pairs = {(row["humanName"], row["robotName"]) for row in rows(live_api.url, "participants")}
    assert pairs == {("Maria", "ARI"), ("Maria", "TIAGo"), ("Carlos", "TIAGo")}

    # ARI and TIAGo heard Maria's first utterance as one shared event, which the server's resolver minted; the
    # utterance TIAGo overheard late, without seeing the speaker, waits for a reviewer.
    shared = select_bindings(live_api.url, SHARED_BY_TWO_ROBOTS)
    assert len(shared) == 1
    assert shared[0]["event"]["value"].startswith("https://gsi.upm.es/segb/shared-events/human_utterance_")
    assert shared_context(live_api.url) == SHARED_CONTEXTS

    assert_nothing_overstated(live_api.url)

    # Carlos's anger, read by TIAGo; and a case the reference reports drop: a state without location.
    carlos = [row for row in rows(live_api.url, "emotion-timeline") if row["targetName"] == "Carlos"]
    assert [(row["category"], row["robotName"]) for row in carlos] == [("anger", "TIAGo")]
    docking = [row for row in rows(live_api.url, "robot-states") if row["value"] == "docking"]
    assert [(row["robotName"], row["location"], row["note"]) for row in docking] == [
        ("TIAGo", None, "Going back to the charger")
    ]
    usage = rows(live_api.url, "ml-usage")
    lineage = {(row["datasetName"], row["score"]) for row in usage if row["robotName"] == "ARI"}
    assert ("FER-2013 facial expressions", 0.71) in lineage

    before = triple_count(live_api.url)
    again = segb("demo", "--server", live_api.url)
    assert again.returncode == 0, again.stderr
    assert "already has the demo dataset" in again.stdout
    assert triple_count(live_api.url) == before


# Maria's four utterances to ARI (one also heard by TIAGo) and Carlos's question: active; the overheard one:
# ambiguous, with its review case.
SHARED_CONTEXTS = {"active_contexts": 5, "ambiguous_contexts": 1, "merged_contexts": 0, "pending_cases": 1}


def shared_context(url: str) -> dict[str, int]:
    stats = httpx.get(f"{url}/shared-context/stats", timeout=30).json()
    return {name: stats[name] for name in SHARED_CONTEXTS}


def assert_nothing_overstated(url: str) -> None:
    """No reply came from a language model (the demo has no Ollama), so none is credited; every emotion a
    robot expressed about itself is told as expressed, never as analysed with a model; words TIAGo overheard
    from a speaker it did not see are nobody's in particular, and never the robot's."""
    overheard = [row for row in rows(url, "conversations") if row["message"].endswith("/message_overheard_1")]
    assert [(row["robotName"], row["speaker"]) for row in overheard] == [("TIAGo", "unidentified")]
    story = httpx.get(f"{url}/explain", params={"iri": overheard[0]["message"]}, timeout=30).json()
    told = next(step for step in story["steps"] if step["role"] == "seed")["sentence"]
    assert told.startswith("An unidentified speaker said “I did not expect") and "heard by TIAGo" in told, told
    assert "TIAGo said" not in told
    usage = rows(url, "ml-usage")
    assert {row["modelName"] for row in usage} == {"Emotion Big6 CNN"}
    expressed = [row for row in rows(url, "emotion-timeline") if row["targetKind"] == "robot"]
    assert len(expressed) == 5  # ARI's four replies, TIAGo's one
    for row in expressed:
        story = httpx.get(f"{url}/explain", params={"iri": row["activity"]}, timeout=30).json()
        seed = next(step for step in story["steps"] if step["role"] == "seed")
        assert f"{row['robotName']} expressed {row['category']} 0.7" in seed["sentence"]
        assert "analysed" not in seed["sentence"]


@pytest.mark.processes
def test_segb_demo_says_when_no_server_answers() -> None:
    server = f"http://127.0.0.1:{free_port()}"
    result = segb("demo", "--server", server)
    assert result.returncode == 2
    assert f"cannot reach the SEGB server at {server}" in result.stderr


@pytest.mark.processes
def test_serve_demo_loads_the_dataset_into_an_empty_store_only(tmp_path: Path) -> None:
    first = serve_demo(tmp_path)
    assert "demo dataset loaded" in first.log
    assert first.participants
    assert first.ledger == 1  # the load has its receipt, like any post
    assert all(name in first.page for name in ("Maria", "Carlos", "ARI", "TIAGo"))  # the UI's /reports is full

    assert first.shared_contexts == SHARED_CONTEXTS  # the resolver's state was filled along with the store

    second = serve_demo(tmp_path)
    assert "demo dataset not loaded: the store already holds" in second.log
    assert second.triples == first.triples
    assert second.participants == first.participants
    assert second.ledger == 1
    assert second.shared_contexts == SHARED_CONTEXTS


@pytest.mark.processes
def test_serve_demo_in_memory_keeps_the_demo_in_the_servers_own_journal_and_resolver(tmp_path: Path) -> None:
    """With STORE=memory the journal and resolver live in the server's memory: the demo must go through the
    server's own, or its receipt and shared events are lost and the journal's sequence restarts under the
    store's, and the next robot's post is taken for one already applied."""
    robot_log = """
        @prefix prov: <http://www.w3.org/ns/prov#> .
        <https://example.org/robot/after-demo> a prov:SoftwareAgent ; prov:wasAssociatedWith <https://example.org/h/z> .
    """

    def publish(api: str) -> None:
        answer = httpx.post(f"{api}/ttl", json={"ttl_content": robot_log, "user": "after-demo"}, timeout=30)
        assert answer.status_code == 201, answer.text
        assert answer.json()["triples_new"] == 2

    served = serve_demo(tmp_path, {"STORE": "memory"}, then=publish)
    assert "demo dataset loaded" in served.log
    assert served.ledger == 1
    assert served.shared_contexts == SHARED_CONTEXTS
    assert served.after_triples == served.triples + 2  # the robot's post reached the store


@dataclass(frozen=True)
class Served:
    log: str
    triples: int
    participants: list[dict[str, Any]]
    ledger: int  # receipts
    page: str  # the UI's /reports page
    shared_contexts: dict[str, int]
    after_triples: int  # after `then` ran


def serve_demo(data_dir: Path, env: dict[str, str] | None = None, then: Callable[[str], None] | None = None) -> Served:
    """Start `segb serve --demo` on free ports, read what a newcomer would see, stop it."""
    api_port, ui_port = free_port(), free_port()
    process = subprocess.Popen(
        [*SEGB, "serve", "--demo", "--data-dir", str(data_dir)],
        env=clean_env({"API_PORT": str(api_port), "UI_PORT": str(ui_port), **(env or {})}),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    api = f"http://127.0.0.1:{api_port}"
    try:
        wait_for(f"{api}/healthz/ready")
        participants = rows(api, "participants")
        triples = triple_count(api)
        ledger = httpx.get(f"{api}/ledger", timeout=30).json()["total"]
        page = wait_for(f"http://127.0.0.1:{ui_port}/reports").text
        contexts = shared_context(api)
        assert_nothing_overstated(api)
        if then is not None:
            then(api)  # answered once the store applied it (INGEST_ACK=auto on the embedded store)
        after_triples = triple_count(api)
    finally:
        process.send_signal(signal.SIGTERM)
        log, _ = process.communicate(timeout=30)
    assert process.returncode == 0, log
    return Served(log, triples, participants, ledger, page, contexts, after_triples)
