"""The emotion-mirror mission controller, instrumented with `semantic-log-generator` as in the SEGB tutorial.

The robot listens to a person, replies (through an LLM or a fixed fallback), and mirrors the facial
expression it detects. Every event is logged and the whole graph is published right after it:

* a detected expression  -> emotion-recognition activity, observation, Big6 emotion annotation on the person;
                            a neutral face has no Big6 category (the client raises on "neutral"): it is logged
                            with no emotion annotation, noted in the Python log, and the robot mirrors nothing;
* an utterance           -> shared event, listening activity, InitialMessage from the person, and the
                            expression read just before linked to that shared event (`schema:about`);
* the reply              -> response activity (using the LLM only when the LLM wrote the reply),
                            ResponseMessage, the robot's mirrored emotion, and a robot state snapshot.

ROS is not needed: a driver (see `driver.py`) calls these three handlers with timestamps.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from rdflib import URIRef
from semantic_log_generator import (
    ActivityKind,
    EmotionScore,
    ModelUsage,
    RobotStateSnapshot,
    SemanticSEGBLogger,
)
from semantic_log_generator.types import SharedEventResolver

ORO = "http://kb.openrobots.org#"
INITIAL_MESSAGE = URIRef(ORO + "InitialMessage")
RESPONSE_MESSAGE = URIRef(ORO + "ResponseMessage")
FACIAL_EXPRESSION = URIRef("http://www.gsi.upm.es/ontologies/amor/ns#FacialExpressionObservation")

FALLBACK_REPLY = "I am here with you. Tell me more."
# A face that shows no emotion. The tutorial's `EmotionCategory.from_expression("neutral")` raises in the client
# (1.0.5): Big6 has no such category, so a neutral face gets no emotion reading.
NEUTRAL = "neutral"

notes = logging.getLogger(__name__)

Replier = Callable[[str], tuple[str, str]]  # utterance -> (reply text, reply source)


def is_neutral(expression: str) -> bool:
    return expression.strip().casefold() == NEUTRAL


def fallback_replier(text: str) -> tuple[str, str]:
    return FALLBACK_REPLY, "fallback"


@dataclass
class Exchange:
    """IRIs minted for one utterance and its reply (what tests and the explanation trace look for)."""

    text: str
    event: URIRef
    listening: URIRef
    heard: URIRef
    response: URIRef | None = None
    said: URIRef | None = None
    reply_source: str | None = None


@dataclass
class RobotConfig:
    robot_id: str = "mirror"
    robot_name: str = "Emotion Mirror"
    base_namespace: str = "https://example.org/segb/robots/mirror/v1/"
    location: str = "living_room"
    llm_label: str = "llama3.2"
    llm_version: str = "3.2"
    llm_provider: str = "Ollama"


@dataclass
class EmotionMirrorMission:
    """One robot's mission. `publish` is called with the logger after every event (may be None offline)."""

    logger: SemanticSEGBLogger
    human: URIRef
    config: RobotConfig
    replier: Replier = fallback_replier
    publish: Callable[[SemanticSEGBLogger], Any] | None = None
    shared_event_namespace: str | None = None
    battery: float = 0.95
    _turn: int = 0
    _last_expression: str | None = None
    _last_recognition: URIRef | None = None
    _recognition_without_event: URIRef | None = None  # read since the last utterance: it joins the next one's event
    _last_heard: URIRef | None = None
    models: dict[str, URIRef] = field(default_factory=dict)

    @classmethod
    def start(
        cls,
        config: RobotConfig,
        *,
        human_id: str,
        human_name: str,
        human: URIRef | None = None,
        shared_event_resolver: SharedEventResolver | None = None,
        **options: Any,
    ) -> EmotionMirrorMission:
        """With `shared_event_resolver` (e.g. the client's HTTPSharedContextResolver), the server decides
        which shared event an utterance belongs to; without, the client's local deterministic fallback does."""
        logger = SemanticSEGBLogger(
            base_namespace=config.base_namespace,
            robot_id=config.robot_id,
            robot_name=config.robot_name,
            compact_resource_ids=True,
            namespace_prefix=config.robot_id,
            shared_event_resolver=shared_event_resolver,
        )
        person = human if human is not None else logger.register_human(human_id, first_name=human_name)
        mission = cls(logger=logger, human=person, config=config, **options)
        mission.models["face"] = logger.register_ml_model(
            "face_emotion",
            label="Emotion Big6 CNN",
            version="1.0",
            provider="GSI-UPM",
            characteristics={"input_size": 48},
        )
        mission.models["llm"] = logger.register_ml_model(
            "llm", label=config.llm_label, version=config.llm_version, provider=config.llm_provider
        )
        mission._publish()
        return mission

    # --- the three handlers the ROS nodes (or the driver) call -------------------------------------------

    def on_face_expression(
        self, expression: str, at: datetime, confidence: float = 0.9, intensity: float | None = None
    ) -> URIRef:
        """The face listener saw `expression` (a Big6 name such as "happy", or "neutral") on the person, this
        strong (`intensity`) and the recogniser this sure of it (`confidence`); a listener that gives one score
        has it stand for both."""
        self._turn += 1
        log = self.logger
        recognition = log.log_activity(
            activity_id=f"recognise_emotion_{self._turn}",
            activity_kind=ActivityKind.EMOTION_RECOGNITION,
            label="Recognise facial expression",
            started_at=at,
            ended_at=at + timedelta(milliseconds=120),
            model_usages=[ModelUsage(model=self.models["face"], parameters={"min_face_size": 48})],
        )
        log.log_observation(
            observation_id=f"face_{self._turn}",
            label=f"Facial expression: {expression}",
            observation_types=[FACIAL_EXPRESSION],
            generated_by_activity=recognition,
        )
        if is_neutral(expression):
            notes.info("a neutral face (turn %d): no Big6 emotion to log or to mirror", self._turn)
            self._last_expression = None
        else:
            strength = confidence if intensity is None else intensity
            log.log_emotion_annotation(
                source_activity=recognition,
                targets=[self.human],
                emotions=[EmotionScore(expression, intensity=strength, confidence=confidence)],
                annotation_id=f"face_emotion_{self._turn}",
            )
            self._last_expression = expression
        self._last_recognition = self._recognition_without_event = recognition
        self._publish()
        return recognition

    def on_user_utterance(self, text: str, at: datetime, language: str = "en") -> Exchange:
        """The intents topic delivered what the person said."""
        self._turn += 1
        log = self.logger
        event = log.get_shared_event_uri(
            event_kind="human_utterance",
            observed_at=at,
            subject=self.human,
            text=text,
            modality="speech",
            shared_event_namespace=self.shared_event_namespace,
        )
        listening = log.log_activity(
            activity_id=f"listen_{self._turn}",
            activity_kind=ActivityKind.LISTENING,
            label="Listen to the user",
            related_shared_events=[event],
            started_at=at,
            ended_at=at + timedelta(milliseconds=800),
        )
        if self._recognition_without_event is not None:
            # As the tutorial's robot logs it: the expression read on the face of the person who now speaks is
            # about this exchange's shared event (which, in turn, is about the person).
            log.link_activity_to_shared_event(self._recognition_without_event, event)
            self._recognition_without_event = None
        heard = log.log_message(
            text,
            message_id=f"user_{self._turn}",
            language=language,
            message_types=[INITIAL_MESSAGE],
            generated_by_activity=listening,
            sender=self.human,
        )
        self._last_heard = heard
        self._publish()
        return Exchange(text=text, event=event, listening=listening, heard=heard)

    def respond(self, exchange: Exchange, at: datetime) -> Exchange:
        """Reply to the last utterance, mirror the last expression, record the robot's state."""
        log = self.logger
        reply, source = self.replier(exchange.text)
        response = log.log_activity(
            activity_id=f"respond_{self._turn}",
            activity_kind=ActivityKind.RESPONSE,
            label=f"Reply to the user ({source})",
            related_shared_events=[exchange.event],
            started_at=at,
            ended_at=at + timedelta(seconds=1),
            triggered_by_activity=self._last_recognition or exchange.listening,
            triggered_by_entity=exchange.heard,
            # As the tutorial logs it: the model is credited only for replies it wrote, never for the fallback.
            used_models=[self.models["llm"]] if source == "ollama" else None,
        )
        said = log.log_message(
            reply,
            message_id=f"robot_{self._turn}",
            language="en",
            message_types=[RESPONSE_MESSAGE],
            generated_by_activity=response,
            previous_message=exchange.heard,
            sender=log.robot_uri,
        )
        if self._last_expression:
            log.log_emotion_annotation(
                source_activity=response,
                targets=[log.robot_uri],
                emotions=[EmotionScore(self._last_expression, intensity=0.7)],
                annotation_id=f"mirrored_emotion_{self._turn}",
            )
        self.battery = max(0.05, self.battery - 0.004)
        log.log_robot_state(
            RobotStateSnapshot(
                timestamp=at + timedelta(seconds=1),
                battery_level=self.battery,
                mission_phase="conversation",
                autonomy_mode="autonomous",
                location=self.config.location,
                custom={"turn": self._turn},
            ),
            state_id=f"state_{self._turn}",
            source_activity=response,
        )
        self._publish()
        exchange.response, exchange.said, exchange.reply_source = response, said, source
        return exchange

    def _publish(self) -> None:
        if self.publish is not None:
            self.publish(self.logger)
