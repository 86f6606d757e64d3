"""A robot log made with the real PyPI client in which every shipped audit rule finds exactly what it is built
for: `troubled()` returns the loggers, the steps and, for each rule, the IRIs of the nodes it must name."""

from __future__ import annotations

from collections.abc import Callable

from rdflib import Literal, URIRef
from rdflib.namespace import PROV, XSD
from semantic_log_generator import ActivityKind, EmotionScore, SemanticSEGBLogger

from tests.support.scenarios import INITIAL, RESPONSE, Scenario, at, robot_logger

SCHEMA_MESSAGE = URIRef("http://schema.org/Message")


def troubled() -> tuple[Scenario, dict[str, set[str]]]:
    """ARI with Maria: one slip of each kind the rules look for, published after every step."""
    ari = robot_logger("ari", "ARI")
    maria = ari.register_human("maria", first_name="Maria")
    expected: dict[str, set[str]] = {}
    steps: list[tuple[str, Callable[[], None]]] = []

    def expect(rule: str, node: URIRef) -> None:
        expected.setdefault(rule, set()).add(str(node))

    def exchange(turn: int, start: float, reply_after: float | None, model: URIRef | None) -> tuple[URIRef, URIRef]:
        event = ari.get_shared_event_uri(
            event_kind="human_utterance", observed_at=at(start), subject=maria, text=f"turn {turn}", modality="speech"
        )
        listening = ari.log_activity(
            activity_id=f"listen_{turn}", activity_kind=ActivityKind.LISTENING, related_shared_events=[event],
            started_at=at(start), ended_at=at(start + 0.8),
        )  # fmt: skip
        heard = ari.log_message(
            f"turn {turn}", message_id=f"heard_{turn}", language="en", message_types=[INITIAL],
            generated_by_activity=listening, sender=maria,
        )  # fmt: skip
        if reply_after is None:
            return heard, listening
        response = ari.log_activity(
            activity_id=f"respond_{turn}", activity_kind=ActivityKind.RESPONSE, related_shared_events=[event],
            started_at=at(start + reply_after), triggered_by_entity=heard,
            used_models=[model] if model is not None else None,
        )  # fmt: skip
        ari.log_message(
            f"reply {turn}", message_id=f"said_{turn}", language="en", message_types=[RESPONSE],
            generated_by_activity=response, previous_message=heard, sender=ari.robot_uri,
        )  # fmt: skip
        return heard, response

    llm = ari.register_ml_model("llm", label="llama3.2", version="3.2", provider="Ollama")
    unversioned = ari.register_ml_model("tagger", label="Tagger")  # registered without a version

    def talk() -> None:
        exchange(1, 0, 1.5, llm)  # answered on time, by the model: clean
        heard, _ = exchange(2, 20, None, None)
        expect("unanswered-message", heard)
        heard, response = exchange(3, 40, 14, llm)
        expect("late-answer", heard)
        _, response = exchange(4, 60, 2, None)
        said = next(ari.graph.subjects(PROV.wasGeneratedBy, response))
        expect("reply-without-model", said)

    def feel() -> None:
        read = ari.log_activity(
            activity_id="read_1", activity_kind=ActivityKind.EMOTION_RECOGNITION, started_at=at(80),
            model_usages=None, used_models=[unversioned],
        )  # fmt: skip
        expect("model-without-version", unversioned)
        ari.log_emotion_annotation(
            source_activity=read, targets=[maria], emotions=[EmotionScore("sad", intensity=0.9, confidence=1.3)],
            annotation_id="read_1",
        )  # fmt: skip
        sadness = _emotion_of(ari, "read_1")
        expect("strong-negative-emotion", sadness)
        expect("emotion-out-of-range", sadness)  # its confidence, 1.3
        event = ari.get_shared_event_uri(
            event_kind="human_utterance", observed_at=at(81), subject=maria, text="look at me", modality="speech"
        )
        respond = ari.log_activity(
            activity_id="respond_mirror", activity_kind=ActivityKind.RESPONSE, related_shared_events=[event],
            started_at=at(82), triggered_by_activity=read, used_models=[llm],
        )  # fmt: skip
        ari.log_emotion_annotation(
            source_activity=respond, targets=[ari.robot_uri], emotions=[EmotionScore("happy", intensity=0.7)],
            annotation_id="shown_1",
        )  # fmt: skip
        expect("mirror-mismatch", _emotion_of(ari, "shown_1"))

    def slip() -> None:
        untimed = ari.log_activity(activity_id="untimed", activity_kind=ActivityKind.DECISION, label="Decide")
        expect("activity-without-start", untimed)
        badly_timed = ari.log_activity(activity_id="badly_timed", activity_kind=ActivityKind.DECISION)
        ari.graph.add((badly_timed, PROV.startedAtTime, Literal("ten past nine", datatype=XSD.string)))
        expect("time-not-datetime", badly_timed)
        mute = ari.log_observation(observation_id="mute", observation_types=[SCHEMA_MESSAGE])
        expect("message-without-text", mute)
        stray = URIRef("https://example.org/segb/robots/ari/v1/note_1")
        ari.link_influence(stray, badly_timed)  # a statement about a resource the log never types
        expect("subject-without-type", stray)

    steps += [("ari", talk), ("ari", feel), ("ari", slip)]
    return Scenario(loggers={"ari": ari}, steps=steps), expected


def _emotion_of(logger: SemanticSEGBLogger, annotation_id: str) -> URIRef:
    annotation = logger.resource_uri("emotion-annotation", annotation_id)
    return next(iter(logger.graph.objects(annotation, URIRef("http://www.gsi.upm.es/ontologies/onyx/ns#hasEmotion"))))


__all__ = ["troubled"]
