"""A scenario with people in it, made with the real PyPI client: robots ARI and TIAGo, visitors Ines, Juan and
Carla in a care home on 2026-03-10. Ines talks to ARI twice (an emotion read on her face each time), TIAGo sees
her at the door; Juan talks to TIAGo, Carla to ARI. No one's words or activity ids name anyone else, so a test
can look for Ines's name, sentences and IRI anywhere after she is erased."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from rdflib import URIRef
from semantic_log_generator import ActivityKind, EmotionScore, ModelUsage, SEGBPublisher, SemanticSEGBLogger

from tests.support.scenarios import INITIAL, RESPONSE, at, robot_logger
from tests.support.settle import settle

INES_SAYS = ("My grandson visits on Sunday", "Thank you, see you tomorrow")
INES_NAME = "Ines"
OTHERS_SAY = ("Where is the cafeteria?", "Is the garden open?")
ROBOT_REPLIES = ("That sounds lovely.", "First floor, on the left.", "Until six this evening.", "Goodbye!")


@dataclass
class Visit:
    loggers: dict[str, SemanticSEGBLogger]
    iris: dict[str, URIRef] = field(default_factory=dict)
    steps: list[tuple[str, Callable[[], None]]] = field(default_factory=list)

    def publish(self, base_url: str, robots: tuple[str, ...] | None = None) -> list[dict]:
        """Each robot's whole graph, as `SemanticSEGBLogger.publish` sends it (a cumulative re-publish)."""
        answers = []
        for name in robots or tuple(self.loggers):
            answers.append(self.loggers[name].publish(SEGBPublisher(base_url=base_url, default_user=name)))
        return answers

    def publish_steps(self, base_url: str) -> None:
        """Every step, the changed robot's whole graph published after each."""
        for robot, step in self.steps:
            step()
            self.publish(base_url, (robot,))
        settle(base_url)


def conversation(
    robot: SemanticSEGBLogger, key: str, human: URIRef, text: str, reply: str, seconds: float, model: URIRef
) -> dict[str, URIRef]:
    """A human says `text` to `robot` (a shared event of it), the robot reads an emotion on their face with
    `model` and replies."""
    event = robot.get_shared_event_uri(
        event_kind="human_utterance", observed_at=at(seconds), subject=human, text=text, modality="speech"
    )
    listen = robot.log_activity(
        activity_id=f"listen_{key}", activity_kind=ActivityKind.LISTENING, related_shared_events=[event],
        started_at=at(seconds),
    )  # fmt: skip
    heard = robot.log_message(
        text, message_id=f"heard_{key}", language="en", message_types=[INITIAL], generated_by_activity=listen,
        sender=human,
    )  # fmt: skip
    read = robot.log_activity(
        activity_id=f"emotion_{key}", activity_kind=ActivityKind.EMOTION_RECOGNITION, related_shared_events=[event],
        started_at=at(seconds + 1), triggered_by_entity=heard, model_usages=[ModelUsage(model=model)],
    )  # fmt: skip
    robot.log_emotion_annotation(source_activity=read, targets=[human], emotions=[EmotionScore("happiness", 0.8)])
    answer = robot.log_activity(
        activity_id=f"reply_{key}", activity_kind=ActivityKind.RESPONSE, related_shared_events=[event],
        started_at=at(seconds + 2), triggered_by_activity=read, triggered_by_entity=heard,
    )  # fmt: skip
    said = robot.log_message(
        reply, message_id=f"said_{key}", message_types=[RESPONSE], generated_by_activity=answer,
        previous_message=heard, sender=robot.robot_uri,
    )  # fmt: skip
    return {"event": event, "heard": heard, "read": read, "reply": answer, "said": said}


def care_home() -> Visit:
    ari, tiago = robot_logger("ari", "ARI"), robot_logger("tiago", "TIAGo")
    visit = Visit({"ari": ari, "tiago": tiago})
    iris = visit.iris
    ines = ari.register_human("v1", first_name=INES_NAME)
    juan = tiago.register_human("v2", first_name="Juan")
    carla = ari.register_human("v3", first_name="Carla")
    iris.update(ines=ines, juan=juan, carla=carla, ari=ari.robot_uri, tiago=tiago.robot_uri)

    def models() -> None:
        iris["cnn"] = ari.register_ml_model("emotion_cnn", label="Emotion Big6 CNN", version="1.0", provider="GSI")
        iris["tiago_cnn"] = tiago.register_ml_model("face_net", label="FaceNet", version="2.1")

    def ines_talks() -> None:
        iris.update(
            {
                f"a1_{k}": v
                for k, v in conversation(ari, "a1", ines, INES_SAYS[0], ROBOT_REPLIES[0], 5, iris["cnn"]).items()
            }
        )

    def tiago_sees_ines() -> None:
        event = tiago.get_shared_event_uri(event_kind="human_entry", observed_at=at(8), subject=ines, modality="vision")
        seen = tiago.log_activity(
            activity_id="detect_t1", activity_kind=ActivityKind.HUMAN_DETECTION, related_shared_events=[event],
            started_at=at(8),
        )  # fmt: skip
        iris["t1_observation"] = tiago.log_observation(
            observation_id="door_t1", label="A visitor at the door", generated_by_activity=seen,
            related_shared_event=event, confidence=0.9,
        )  # fmt: skip
        iris.update(t1_event=event, t1_detect=seen)

    def juan_talks() -> None:
        iris.update(
            {
                f"t2_{k}": v
                for k, v in conversation(
                    tiago, "t2", juan, OTHERS_SAY[0], ROBOT_REPLIES[1], 12, iris["tiago_cnn"]
                ).items()
            }
        )

    def carla_talks() -> None:
        iris.update(
            {
                f"a3_{k}": v
                for k, v in conversation(ari, "a3", carla, OTHERS_SAY[1], ROBOT_REPLIES[2], 20, iris["cnn"]).items()
            }
        )

    def ines_again() -> None:
        iris.update(
            {
                f"a4_{k}": v
                for k, v in conversation(ari, "a4", ines, INES_SAYS[1], ROBOT_REPLIES[3], 30, iris["cnn"]).items()
            }
        )

    visit.steps = [
        ("ari", models), ("ari", ines_talks), ("tiago", tiago_sees_ines), ("tiago", juan_talks),
        ("ari", carla_talks), ("ari", ines_again),
    ]  # fmt: skip
    return visit


def filler(subjects: int) -> str:
    """Other robots' data to make a store big (two triples a subject, typed, so no audit rule finds anything in it),
    as N-Triples: the embedded store then takes seconds to be written anew by an erasure."""
    return "".join(
        f"<https://example.org/filler/s{n}> <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> "
        f'<https://example.org/Filler> .\n<https://example.org/filler/s{n}> <https://example.org/p> "value {n}" .\n'
        for n in range(subjects)
    )
