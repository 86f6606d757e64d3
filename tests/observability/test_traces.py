"""Traces of what robots did, over OTLP/HTTP to a local receiver: live as the demo is applied, one trace per
interaction with its models under the GenAI conventions; message lengths, never texts or names unless allowed;
on demand for a window (`segb export --otlp`); nothing about an erased person afterwards; an unreachable
endpoint never slows a post."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.cli import main
from tests.conftest import make_settings
from tests.observability.otlp_receiver import OtlpReceiver, ReceivedSpan
from tests.support.in_process import InProcess
from tests.support.net import free_port
from tests.support.settle import settle

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
MARIA = "https://example.org/segb/robots/ari/v1/human_maria"
NAMES = ("Maria", "Carlos")


def demo_spans(receiver: OtlpReceiver, **settings: object) -> list[ReceivedSpan]:
    with InProcess(create_app(make_settings(otel_exporter_otlp_endpoint=receiver.endpoint, **settings), demo=True)):
        receiver.wait_for(1)
        return receiver.settled()


def values(spans: list[ReceivedSpan]) -> list[str]:
    return [str(value) for span in spans for value in span.attributes.values()]


def test_the_demo_is_traced_live_an_interaction_a_trace_with_its_models() -> None:
    with OtlpReceiver() as receiver:
        spans = demo_spans(receiver)
    by_id = {span.span_id: span for span in spans}
    roots = [span for span in spans if not span.parent_id]
    assert roots and all(span.name == "interaction" for span in roots)
    assert len({span.span_id for span in spans}) == len(spans)  # each span sent once
    kinds = {span.name for span in spans}
    assert {"listening", "response", "emotion-recognition", "state"} <= kinds
    for span in spans:
        assert span.parent_id == "" or by_id[span.parent_id].trace_id == span.trace_id  # parents in their trace
    models = [span for span in spans if span.attributes.get("openinference.span.kind") == "LLM"]
    assert models and all(
        span.attributes["gen_ai.request.model"] and span.attributes["gen_ai.system"] for span in models
    )
    assert {"chat", "inference"} >= {span.attributes["gen_ai.operation.name"] for span in models}
    assert any(span.attributes.get("segb.model.version") for span in models)
    responses = [span for span in spans if span.name == "response"]
    assert any(span.links for span in responses)  # triggered by what the robot heard
    heard = [span for span in spans if span.name == "listening" and span.attributes.get("segb.robot") == ARI]
    assert heard and heard[0].attributes["segb.human"] == MARIA
    assert heard[0].attributes["segb.message.0.speaker"] == "human"
    assert (
        isinstance(heard[0].attributes["segb.message.0.length"], int)
        and heard[0].attributes["segb.message.0.length"] > 0
    )
    assert not any(
        key.endswith(".text") or key in ("input.value", "output.value") for s in spans for key in s.attributes
    )
    assert not any(name in value for value in values(spans) for name in NAMES)  # ids, never names


def test_message_texts_are_sent_only_when_allowed() -> None:
    with OtlpReceiver() as receiver:
        spans = demo_spans(receiver, trace_message_text=True)
    texts = [value for span in spans for key, value in span.attributes.items() if key.endswith(".text")]
    assert texts and all(isinstance(text, str) and text for text in texts)


def test_a_window_is_exported_on_demand_and_an_erased_person_is_not_sent_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = make_settings(store="oxigraph", data_dir=tmp_path)
    with InProcess(create_app(settings, demo=True)) as api:
        erased = api.post("/humans/erase", json={"iri": MARIA, "reason": "request 1"})
        assert erased.status_code < 300, erased.text
        settle(api.client)
    with OtlpReceiver() as receiver:
        monkeypatch.setenv("OTEL_EXPORTER_OTLP_ENDPOINT", receiver.endpoint)
        monkeypatch.chdir(tmp_path)  # no .env of the developer's
        assert main(["export", "--otlp", "--data-dir", str(tmp_path), "--robot", ARI]) == 0
        spans = receiver.settled()
    assert spans and {span.attributes.get("segb.robot") for span in spans} - {None} == {ARI}
    assert not any(MARIA in value for value in values(spans))


def test_export_refuses_a_bad_window_or_a_missing_endpoint_in_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("OTEL_EXPORTER_OTLP_ENDPOINT", raising=False)
    assert main(["export", "--otlp", "--data-dir", str(tmp_path)]) == 2
    assert "set OTEL_EXPORTER_OTLP_ENDPOINT" in capsys.readouterr().err
    monkeypatch.setenv("OTEL_EXPORTER_OTLP_ENDPOINT", f"http://127.0.0.1:{free_port()}")
    assert main(["export", "--otlp", "--data-dir", str(tmp_path), "--since", "yesterday"]) == 2
    said = capsys.readouterr().err.strip()
    assert said.startswith("segb: error: Parameter 'since'") and "\n" not in said


def test_an_unreachable_endpoint_never_slows_or_fails_a_post() -> None:
    nowhere = f"http://127.0.0.1:{free_port()}"
    started = time.monotonic()
    with InProcess(create_app(make_settings(otel_exporter_otlp_endpoint=nowhere), demo=True)) as api:
        loaded = time.monotonic() - started
        posted = api.post("/ttl", content=f"<{ARI}> <http://schema.org/name> 'ARI' .",
                          headers={"content-type": "text/turtle"})  # fmt: skip
        assert posted.status_code == 201
        assert api.get("/healthz/ready").status_code == 200
    assert loaded < 60
