"""Scenarios built with the real PyPI client, where the right answer of every report is known by construction.

`lobby()` is a hospital lobby on 2026-03-10: robots ARI and TIAGo, humans Maria and Juan, talking in
overlapping time. Each step changes one robot's graph; `publish_all` publishes the changed robot's *whole*
graph after every step, as `SemanticSEGBLogger.publish()` does on a real robot.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta

from rdflib import URIRef
from semantic_log_generator import (
    ActivityKind,
    EmotionScore,
    ModelUsage,
    RobotStateSnapshot,
    SemanticSEGBLogger,
)

from tests.support.in_process import Server, http, publisher_for
from tests.support.settle import settle

ORO = "http://kb.openrobots.org#"
INITIAL = URIRef(ORO + "InitialMessage")
RESPONSE = URIRef(ORO + "ResponseMessage")
T0 = datetime(2026, 3, 10, 9, 0, 0, tzinfo=UTC)


def at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def robot_logger(name: str, display: str) -> SemanticSEGBLogger:
    return SemanticSEGBLogger(
        base_namespace=f"https://example.org/segb/robots/{name}/v1/",
        robot_id=name,
        robot_name=display,
        compact_resource_ids=True,
        namespace_prefix=name,
    )


@dataclass
class Scenario:
    """Loggers, the steps that fill them, and the IRIs tests look for."""

    loggers: dict[str, SemanticSEGBLogger]
    steps: list[tuple[str, Callable[[], None]]]
    iris: dict[str, URIRef] = field(default_factory=dict)

    def run_steps(self, after_step: Callable[[str], None] | None = None) -> None:
        for robot, step in self.steps:
            step()
            if after_step is not None:
                after_step(robot)

    def publish_all(self, server: Server, token: str | None = None) -> list[dict]:
        """Run every step, publishing the changed robot's whole graph after each; return the responses once the
        server shows every post in its reports. `server`: a live server's URL or an in-process app's client."""
        publishers = {name: publisher_for(server, name, token) for name in self.loggers}
        responses: list[dict] = []
        self.run_steps(lambda robot: responses.append(self.loggers[robot].publish(publishers[robot])))
        settle(server)
        return responses

    def published_turtle(self) -> list[str]:
        """What the robots send: each logger's graph as the client serialises it (rdflib Turtle)."""
        return [logger.serialize() for logger in self.loggers.values()]


def lobby() -> Scenario:
    """Two robots, two humans, overlapping conversations, and every shape the reports must handle."""
    ari = robot_logger("ari", "ARI")
    tiago = robot_logger("tiago", "TIAGo")
    maria = ari.register_human("maria", first_name="Maria")
    juan = ari.register_human("juan", first_name="Juan")
    scenario = Scenario(loggers={"ari": ari, "tiago": tiago}, steps=[])
    iris = scenario.iris
    iris.update(ari=ari.robot_uri, tiago=tiago.robot_uri, maria=maria, juan=juan)

    def ari_models() -> None:
        cnn = ari.register_ml_model("emotion_cnn", label="Emotion Big6 CNN", version="1.0", provider="GSI")
        dataset = ari.register_dataset("faces_v1", label="Faces v1")
        score = ari.register_model_evaluation("emotion_cnn_acc", value=0.91, label="Accuracy")
        run = ari.log_activity(
            activity_id="train_emotion_cnn",
            activity_kind=ActivityKind.ML_RUN,
            label="Train emotion CNN",
            started_at=at(-86400),
            ended_at=at(-82800),
        )
        ari.link_ml_run_input(run, dataset)
        ari.link_ml_run_output(run, cnn)
        ari.link_ml_run_output(run, score)
        iris.update(emotion_cnn=cnn, faces_v1=dataset, emotion_cnn_acc=score, train_run=run)

    def tiago_models() -> None:
        iris["llm"] = tiago.register_ml_model("llm", label="Llama 3", version="3.1", provider="Meta")

    def maria_arrives() -> None:
        event = ari.get_shared_event_uri(event_kind="human_entry", observed_at=at(0), subject=maria, modality="vision")
        iris["detect_maria"] = ari.log_activity(
            activity_id="detect_maria",
            activity_kind=ActivityKind.HUMAN_DETECTION,
            related_shared_events=[event],
            started_at=at(0),
        )

    def maria_speaks() -> None:
        text = "I passed my driving test today!"
        event = ari.get_shared_event_uri(
            event_kind="human_utterance", observed_at=at(5), subject=maria, text=text, modality="speech"
        )
        listen = ari.log_activity(
            activity_id="listen_maria_1",
            activity_kind=ActivityKind.LISTENING,
            related_shared_events=[event],
            started_at=at(5),
            ended_at=at(6),
        )
        heard = ari.log_message(
            text,
            message_id="maria_1",
            language="en",
            message_types=[INITIAL],
            generated_by_activity=listen,
            sender=maria,
        )
        emotion = ari.log_activity(
            activity_id="emotion_maria_1",
            activity_kind=ActivityKind.EMOTION_RECOGNITION,
            related_shared_events=[event],
            started_at=at(6),
            triggered_by_entity=heard,
            model_usages=[ModelUsage(model=iris["emotion_cnn"], parameters={"threshold": 0.5})],
        )
        ari.log_emotion_annotation(
            source_activity=emotion, targets=[maria], emotions=[EmotionScore("happiness", 0.9, 0.95)]
        )
        reply = ari.log_activity(
            activity_id="reply_maria_1",
            activity_kind=ActivityKind.RESPONSE,
            related_shared_events=[event],
            started_at=at(8),
            triggered_by_activity=emotion,
            triggered_by_entity=heard,
        )
        said = ari.log_message(
            "Congratulations, Maria!",
            message_id="ari_1",
            message_types=[RESPONSE],
            generated_by_activity=reply,
            previous_message=heard,
            sender=ari.robot_uri,
        )
        iris.update(listen_maria_1=listen, maria_1=heard, emotion_maria_1=emotion, reply_maria_1=reply, ari_1=said)

    def juan_speaks() -> None:
        text = "Where is the pharmacy?"
        event = tiago.get_shared_event_uri(
            event_kind="human_utterance", observed_at=at(7), subject=juan, text=text, modality="speech"
        )
        listen = tiago.log_activity(
            activity_id="listen_juan_1",
            activity_kind=ActivityKind.LISTENING,
            related_shared_events=[event],
            started_at=at(7),
        )
        heard = tiago.log_message(
            text,
            message_id="juan_1",
            language="es",
            message_types=[INITIAL],
            generated_by_activity=listen,
            sender=juan,
        )
        reply = tiago.log_activity(
            activity_id="reply_juan_1",
            activity_kind=ActivityKind.RESPONSE,
            related_shared_events=[event],
            started_at=at(9),
            triggered_by_entity=heard,
            model_usages=[
                ModelUsage(
                    model=iris["llm"], parameters={"temperature": 0.7}, software_label="ollama", software_version="0.3"
                )
            ],
        )
        said = tiago.log_message(
            "Second floor, Juan.",
            message_id="tiago_1",
            message_types=[RESPONSE],
            generated_by_activity=reply,
            previous_message=heard,
            sender=tiago.robot_uri,
        )
        iris.update(listen_juan_1=listen, juan_1=heard, reply_juan_1=reply, tiago_1=said)

    def ari_state() -> None:
        iris["ari_state"] = ari.log_robot_state(
            RobotStateSnapshot(timestamp=at(10), battery_level=0.82, mission_phase="greeting", location="room_a"),
            state_id="ari_state_1",
        )

    def juan_emotion_without_event() -> None:
        # No related_shared_events: the reference report loses this emotion.
        emotion = tiago.log_activity(
            activity_id="emotion_juan_1", activity_kind=ActivityKind.EMOTION_RECOGNITION, started_at=at(12)
        )
        tiago.log_emotion_annotation(source_activity=emotion, targets=[juan], emotions=[EmotionScore("anger", 0.8)])
        iris["emotion_juan_1"] = emotion

    def ari_expresses() -> None:
        expression = ari.log_activity(
            activity_id="express_ari_1", activity_kind=ActivityKind.EMOTION_ANALYSIS, started_at=at(15)
        )
        ari.log_emotion_annotation(
            source_activity=expression, targets=[ari.robot_uri], emotions=[EmotionScore("happiness", 0.6)]
        )
        iris["express_ari_1"] = expression

    def tiago_state() -> None:
        # No location: the reference displacement report drops it.
        iris["tiago_state"] = tiago.log_robot_state(
            RobotStateSnapshot(timestamp=at(18), battery_level=41.5, custom={"arm_calibrated": True}),
            state_id="tiago_state_1",
        )

    def maria_thanks() -> None:
        listen = ari.log_activity(activity_id="listen_maria_2", activity_kind=ActivityKind.LISTENING, started_at=at(20))
        heard = ari.log_message(
            "Thanks!",
            message_id="maria_2",
            language="en",
            message_types=[INITIAL],
            generated_by_activity=listen,
            sender=maria,
            previous_message=iris["ari_1"],
        )
        iris.update(listen_maria_2=listen, maria_2=heard)

    scenario.steps = [
        ("ari", ari_models),
        ("tiago", tiago_models),
        ("ari", maria_arrives),
        ("ari", maria_speaks),
        ("tiago", juan_speaks),
        ("ari", ari_state),
        ("tiago", juan_emotion_without_event),
        ("ari", ari_expresses),
        ("tiago", tiago_state),
        ("ari", maria_thanks),
    ]
    return scenario


def keep_busy(server: Server, robot: str, activities: int) -> None:
    """Publish `activities` activities performed by `robot`: the object of that many links, as after a month."""
    busy = "\n".join(
        f"<https://example.org/busy/a{i}> <http://www.gsi.upm.es/ontologies/segb/ns#wasPerformedBy> <{robot}> ."
        for i in range(activities)
    )
    assert http(server, "POST", "/ttl", json={"ttl_content": busy}).status_code == 201


def publish_message(server: Server, text: str, token: str | None = None) -> str:
    """What ARI logs when it hears Maria say `text`, published by the robots' client; the message's IRI."""
    robot = robot_logger("ari", "ARI")
    maria = robot.register_human("maria", first_name="Maria")
    key = hashlib.sha256(text.encode()).hexdigest()[:12]
    heard = robot.log_activity(activity_id=f"listen_{key}", activity_kind=ActivityKind.LISTENING, started_at=at(600))
    message = robot.log_message(
        text, message_id=f"live_{key}", sender=maria, language="en", generated_by_activity=heard
    )
    publisher_for(server, token=token).publish_turtle(robot.serialize())
    return str(message)
