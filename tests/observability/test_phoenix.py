"""A real Arize Phoenix receives the traces: the demo's interactions, live as it is applied, with their robots and
models; and a window sent on demand by the `segb` command. Read back through Phoenix's REST API."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from segb_server.backend.api.app import create_app
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from tests.conftest import make_settings
from tests.observability.phoenix import PhoenixProcess
from tests.support.in_process import InProcess, publisher_for
from tests.support.scenarios import at
from tests.support.settle import settle

pytestmark = pytest.mark.processes

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
TIAGO = "https://example.org/segb/robots/tiago/v1/robot_tiago"
MIRROR = "https://example.org/segb/robots/mirror/v1/robot_mirror"


@pytest.fixture(scope="module")
def phoenix() -> Iterator[PhoenixProcess]:
    process = PhoenixProcess()
    process.start()
    yield process
    process.stop()


def settled(phoenix: PhoenixProcess, project: str) -> list[dict[str, object]]:
    """Phoenix's spans of `project` once their count stops growing."""
    count = -1
    while True:
        spans = phoenix.spans_when(project, max(count + 1, 1), timeout=5 if count >= 0 else 60)
        if len(spans) == count:
            return spans
        count = len(spans)


def attributes(span: dict[str, object]) -> dict[str, object]:
    return span["attributes"]  # type: ignore[return-value]


def test_phoenix_shows_the_demo_interactions_with_their_models(phoenix: PhoenixProcess) -> None:
    with InProcess(create_app(make_settings(otel_exporter_otlp_endpoint=phoenix.url), demo=True)):
        spans = settled(phoenix, "segb")
    robots = {attributes(span).get("segb.robot") for span in spans}
    assert {ARI, TIAGO} <= robots
    interactions = [span for span in spans if span["name"] == "interaction"]
    assert interactions and all(span.get("parent_id") is None for span in interactions)
    traces = {span["context"]["trace_id"] for span in interactions}  # type: ignore[index]
    models = [span for span in spans if "gen_ai.request.model" in attributes(span)]
    assert models and all(span["context"]["trace_id"] in traces for span in models)  # type: ignore[index]
    assert all(span.get("parent_id") for span in models)  # under the activity that invoked them
    assert {"Emotion Big6 CNN"} <= {attributes(span)["gen_ai.request.model"] for span in models}
    assert all(attributes(span)["gen_ai.system"] for span in models)
    by_trace: dict[str, set[object]] = {}
    for span in spans:
        by_trace.setdefault(span["context"]["trace_id"], set()).add(attributes(span).get("segb.robot"))  # type: ignore[index]
    assert any({ARI, TIAGO} <= robots for robots in by_trace.values())  # what both heard: one interaction


def test_a_window_sent_by_the_segb_command_reaches_phoenix(phoenix: PhoenixProcess, tmp_path: Path) -> None:
    """The emotion mirror's log (not the demo's: Phoenix keeps the first copy of a span it is sent twice)."""
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as api:
        publisher = publisher_for(api.client, "mirror")
        mission = EmotionMirrorMission.start(
            RobotConfig(), human_id="maria", human_name="Maria", publish=lambda logger: logger.publish(publisher)
        )
        mission.on_face_expression("happy", at(-1))
        mission.respond(mission.on_user_utterance("Are you there?", at(0)), at(1.5))
        settle(api.client)
    env = {
        **os.environ,
        "OTEL_EXPORTER_OTLP_ENDPOINT": phoenix.url,
        "OTEL_RESOURCE_ATTRIBUTES": "openinference.project.name=segb-window",
    }
    done = subprocess.run(
        ["segb", "export", "--otlp", "--data-dir", str(tmp_path), "--robot", MIRROR, "--since", "2000-01-01T00:00:00Z"],
        env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "spans to" in done.stderr
    spans = settled(phoenix, "segb-window")
    assert {attributes(span).get("segb.robot") for span in spans} - {None} == {MIRROR}
    assert {"interaction", "listening", "response", "emotion-recognition"} <= {span["name"] for span in spans}
