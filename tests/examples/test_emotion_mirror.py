"""The emotion-mirror robot, driven by its runner against a live API, read back through the audit reports."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import httpx
import pytest
from semantic_log_generator import SEGBPublisher

from segb_server.examples.emotion_mirror import run
from segb_server.examples.emotion_mirror.mission import FALLBACK_REPLY, EmotionMirrorMission, RobotConfig
from segb_server.examples.emotion_mirror.script import Expression, Utterance, default_script
from tests.support.live_server import LiveServer
from tests.support.net import free_port
from tests.support.settle import settle
from tests.support.sparql import select_bindings

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_SCRIPT = ROOT / "examples" / "emotion_mirror" / "sample_script.json"
RESPONSE_LABELS = """
PREFIX oro: <http://kb.openrobots.org#>
PREFIX rdfs: <http://www.w3.org/2000/01/rdf-schema#>
SELECT ?label WHERE { ?activity a oro:ResponseAction ; rdfs:label ?label } ORDER BY ?activity
"""


def closed_port_url() -> str:
    """An address where nothing listens: no Ollama (or SEGB) server can answer there."""
    return f"http://127.0.0.1:{free_port()}"


def drive(server: LiveServer, *extra: str) -> int:
    # --ollama-host points at a closed port so the fallback is used even where an Ollama server runs.
    return run.main(["--server", server.url, "--ollama-host", closed_port_url(), *extra])


def report(server: LiveServer, name: str, **params: str) -> list[dict[str, Any]]:
    settle(server.url)  # the reports are rows kept current from the journal: read them once they include every post
    response = httpx.get(f"{server.url}/reports/{name}", params=params, timeout=30)
    assert response.status_code == 200, response.text
    return response.json()["rows"]


def test_the_default_script_fills_the_four_tutorial_reports(
    live_api: LiveServer, capsys: pytest.CaptureFixture[str]
) -> None:
    assert drive(live_api) == 0
    printed = capsys.readouterr().out.splitlines()
    assert len(printed) == 1 + 12  # the start, then 4 expressions, 4 utterances and 4 replies
    assert all("new of" in line for line in printed)
    assert sum("[fallback]" in line for line in printed) == 4

    participants = report(live_api, "participants")
    assert [(row["humanName"], row["robotName"]) for row in participants] == [("Maria", "Emotion Mirror")]
    assert participants[0]["robot"].endswith("/robot_mirror")
    assert participants[0]["interactions"] == 12  # 4 recognitions, 4 listenings, 4 responses

    # Every reply came from the fallback: the language model wrote none of them and is credited with none.
    usage = report(live_api, "ml-usage")
    models = {(row["activityKind"], row["modelName"], row["version"], row["provider"]) for row in usage}
    assert models == {("emotion-recognition", "Emotion Big6 CNN", "1.0", "GSI-UPM")}
    assert len(usage) == 4

    timeline = report(live_api, "emotion-timeline")
    read = [row for row in timeline if row["targetKind"] == "human"]
    assert [row["category"] for row in read] == ["happiness", "surprise", "sadness", "happiness"]
    assert [row["intensity"] for row in read] == [0.92, 0.81, 0.64, 0.95]
    assert {row["targetName"] for row in read} == {"Maria"}
    seen = [event.at for event in default_script().events if isinstance(event, Expression)]
    assert [row["time"] for row in read] == [at.strftime("%Y-%m-%dT%H:%M:%SZ") for at in seen]
    mirrored = [row["category"] for row in timeline if row["targetKind"] == "robot"]
    assert mirrored == ["happiness", "surprise", "sadness", "happiness"]  # the robot mirrors what it read

    conversation = report(live_api, "conversations")
    said = [event.text for event in default_script().events if isinstance(event, Utterance)]
    expected = [turn for text in said for turn in (("human", text), ("robot", FALLBACK_REPLY))]
    assert [(row["speaker"], row["text"]) for row in conversation] == expected
    assert {(row["humanName"], row["robotName"]) for row in conversation} == {("Maria", "Emotion Mirror")}
    assert [row["time"] for row in conversation] == sorted(row["time"] for row in conversation)

    # Where each reply came from is in the response activity's label.
    replies = select_bindings(live_api.url, RESPONSE_LABELS)
    assert [binding["label"]["value"] for binding in replies] == ["Reply to the user (fallback)"] * 4

    # The robot's mirrored emotion is told as expressed, never as analysed with a model.
    for row in timeline:
        if row["targetKind"] == "robot":
            story = httpx.get(f"{live_api.url}/explain", params={"iri": row["activity"]}, timeout=30).json()
            seed = next(step for step in story["steps"] if step["role"] == "seed")
            assert f"Emotion Mirror expressed {row['category']} 0.7" in seed["sentence"]
            assert "analysed" not in seed["sentence"] and "llama" not in seed["sentence"]

    # Each utterance's shared event was minted by the server's resolver, not by the client's local fallback.
    stats = httpx.get(f"{live_api.url}/shared-context/stats", timeout=10).json()
    assert (stats["active_contexts"], stats["ambiguous_contexts"]) == (len(said), 0)
    events = select_bindings(
        live_api.url,
        "SELECT DISTINCT ?event WHERE { ?activity <http://schema.org/about> ?event . "
        "?event a <http://schema.org/Event> }",
    )
    server_minted = re.compile(r"https://gsi\.upm\.es/segb/shared-events/human_utterance_[0-9a-f]{16}")
    assert len(events) == len(said)
    assert all(server_minted.fullmatch(binding["event"]["value"]) for binding in events)


def test_a_script_file_is_replayed_in_time_order(live_api: LiveServer, tmp_path: Path) -> None:
    script = json.loads(SAMPLE_SCRIPT.read_text(encoding="utf-8"))
    script["events"].reverse()  # written out of order: replayed by time all the same
    shuffled = tmp_path / "script.json"
    shuffled.write_text(json.dumps(script), encoding="utf-8")

    assert drive(live_api, "--script", str(shuffled)) == 0
    assert [row["humanName"] for row in report(live_api, "participants")] == ["Leo"]
    timeline = report(live_api, "emotion-timeline", threshold="0.6")
    assert [(row["time"], row["category"]) for row in timeline if row["targetKind"] == "human"] == [
        ("2026-03-11T16:30:00Z", "fear"),
        ("2026-03-11T16:30:09Z", "surprise"),
    ]
    conversation = report(live_api, "conversations")
    assert [(row["time"], row["speaker"]) for row in conversation] == [
        ("2026-03-11T16:30:02Z", "human"),
        ("2026-03-11T16:30:03.5Z", "robot"),
        ("2026-03-11T16:30:10Z", "human"),
        ("2026-03-11T16:30:12Z", "robot"),
    ]


def test_a_bad_script_is_refused_before_anything_is_published(
    live_api: LiveServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"human": {"id": "x", "name": "X"}, "events": [{"at": 0, "expression": "bored"}]}))
    assert drive(live_api, "--script", str(bad)) == 2
    assert "events[0].expression 'bored' is not a Big6 emotion" in capsys.readouterr().err
    assert report(live_api, "participants") == []
    assert httpx.get(f"{live_api.url}/events", params={"format": "ntriples"}).text.strip() == ""


@pytest.mark.processes
def test_an_unreachable_server_fails_with_a_clear_message() -> None:
    server = closed_port_url()
    result = subprocess.run(
        [sys.executable, "-m", "segb_server.examples.emotion_mirror.run", "--server", server],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    assert f"cannot reach the SEGB server at {server}" in result.stderr
    assert "segb serve" in result.stderr
    assert result.stdout == ""


def test_the_language_model_is_credited_only_for_the_replies_it_wrote(live_api: LiveServer) -> None:
    """As the tutorial logs it: `used_models=[chat_model] if reply_source == "ollama" else None`."""
    answers = iter([("Congratulations!", "ollama"), (FALLBACK_REPLY, "fallback")])
    publisher = SEGBPublisher(base_url=live_api.url)
    mission = EmotionMirrorMission.start(
        RobotConfig(),
        human_id="maria",
        human_name="Maria",
        replier=lambda text: next(answers),
        publish=lambda logger: logger.publish(publisher),
    )
    at = datetime(2026, 3, 10, 10, 0, tzinfo=UTC)
    for turn, text in enumerate(["I passed!", "Thanks."]):
        mission.respond(
            mission.on_user_utterance(text, at + timedelta(seconds=10 * turn)), at + timedelta(seconds=10 * turn + 2)
        )

    usage = report(live_api, "ml-usage")
    assert [(row["modelName"], row["activityName"]) for row in usage] == [("llama3.2", "Reply to the user (ollama)")]
    replies = report(live_api, "conversations")
    generated = next(row for row in replies if row["text"] == "Congratulations!")
    story = httpx.get(f"{live_api.url}/explain", params={"iri": generated["message"]}, timeout=30).json()
    seed = next(step for step in story["steps"] if step["role"] == "seed")
    assert seed["sentence"] == "Emotion Mirror said “Congratulations!” with llama3.2 3.2"


def test_running_the_script_again_is_warned_about(live_api: LiveServer, capsys: pytest.CaptureFixture[str]) -> None:
    assert drive(live_api) == 0
    assert "warning" not in capsys.readouterr().err
    assert drive(live_api) == 0
    printed = capsys.readouterr()
    assert "-> 0 new of 29 triples" in printed.out.splitlines()[0]
    assert "emotion_mirror: warning: the server already holds Emotion Mirror's log with Maria" in printed.err
    assert "emotion timeline will show each reading twice" in printed.err
