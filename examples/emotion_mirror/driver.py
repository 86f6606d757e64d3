"""Replaying a script into the mission: the part the ROS topics play on the real robot.

Each expression goes to `on_face_expression`; each utterance to `on_user_utterance` and is answered
with `respond` at its reply time. The mission publishes after every handler call; `play` yields one
`Step` after each, so a caller can report what was just published.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from typing import Literal

from rdflib import URIRef

from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, is_neutral
from segb_server.examples.emotion_mirror.script import Expression, Script

SCHEMA_TEXT = URIRef("http://schema.org/text")


@dataclass(frozen=True)
class Step:
    """One replayed event: when, what, a one-line description, and the main IRI it minted."""

    at: datetime
    kind: Literal["expression", "utterance", "reply"]
    description: str
    iri: URIRef
    reply_source: str | None = None


def play(mission: EmotionMirrorMission, script: Script) -> Iterator[Step]:
    person = script.human_name
    for event in script.events:
        if isinstance(event, Expression):
            recognition = mission.on_face_expression(
                event.expression, event.at, confidence=event.confidence, intensity=event.intensity
            )
            seen = f"{person} looks {event.expression} ({event.confidence:.2f})"
            if is_neutral(event.expression):
                seen += ": no Big6 emotion, none logged"
            yield Step(event.at, "expression", seen, recognition)
            continue
        exchange = mission.on_user_utterance(event.text, event.at)
        yield Step(event.at, "utterance", f"{person}: {event.text}", exchange.heard)
        mission.respond(exchange, event.reply_at)
        assert exchange.said is not None  # respond() always sets it
        reply = mission.logger.graph.value(exchange.said, SCHEMA_TEXT)
        robot = mission.config.robot_name
        yield Step(event.reply_at, "reply", f"{robot}: {reply}", exchange.said, exchange.reply_source)
