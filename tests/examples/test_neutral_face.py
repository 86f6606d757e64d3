"""A neutral face in front of the emotion-mirror robot. The client (semantic-log-generator 1.0.5) has no Big6
category for it and raises, so the robot logs the recognition and what it saw, no emotion reading, and mirrors
nothing, with a note saying so."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import httpx
import pytest
from semantic_log_generator import EmotionCategory

from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from tests.examples.test_emotion_mirror import drive, report
from tests.support.live_server import LiveServer
from tests.support.scenarios import at

NEUTRAL_VISIT = {
    "human": {"id": "ines", "name": "Ines"},
    "start": "2026-03-12T09:00:00Z",
    "events": [
        {"at": 0, "expression": "happy", "confidence": 0.9},
        {"at": 1, "says": "Good morning!"},
        {"at": 5, "expression": "neutral", "confidence": 0.88},
        {"at": 6, "says": "What time is it?"},
    ],
}


def test_the_client_has_no_category_for_a_neutral_face() -> None:
    with pytest.raises(ValueError, match="neutral"):
        EmotionCategory.from_expression("neutral")


def test_a_neutral_face_is_logged_with_no_emotion_reading_and_nothing_mirrored(
    live_api: LiveServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "neutral.json"
    script.write_text(json.dumps(NEUTRAL_VISIT), encoding="utf-8")

    assert drive(live_api, "--script", str(script)) == 0
    printed = capsys.readouterr().out
    assert "Ines looks neutral (0.88): no Big6 emotion, none logged" in printed

    timeline = report(live_api, "emotion-timeline")
    assert [(row["time"], row["category"], row["targetKind"]) for row in timeline] == [
        ("2026-03-12T09:00:00Z", "happiness", "human"),
        ("2026-03-12T09:00:02.5Z", "happiness", "robot"),  # the first reply mirrors the happy face
    ]  # the neutral face: no reading, and the second reply mirrors nothing
    observed = httpx.get(f"{live_api.url}/events", params={"format": "ntriples"}, timeout=30).text
    assert '"Facial expression: neutral"' in observed  # what the robot saw is logged all the same
    assert len(report(live_api, "conversations")) == 4


def test_the_mission_notes_a_neutral_face_in_its_log(caplog: pytest.LogCaptureFixture) -> None:
    mission = EmotionMirrorMission.start(RobotConfig(), human_id="ines", human_name="Ines")
    with caplog.at_level(logging.INFO, logger="segb_server.examples.emotion_mirror.mission"):
        mission.on_face_expression("Neutral", at(0))
    assert any("neutral face" in record.getMessage() for record in caplog.records)
