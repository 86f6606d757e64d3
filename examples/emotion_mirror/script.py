"""What the person does in front of the robot, as a list of timed events: the input the driver replays.

A script file is JSON:

    {"human": {"id": "maria", "name": "Maria"},
     "start": "2026-03-10T10:00:00Z",
     "events": [{"at": 0, "expression": "happy", "intensity": 0.92, "confidence": 0.87},
                {"at": 1, "says": "I passed my driving test today!", "reply_after": 1.5}]}

`at` is seconds after `start`. An expression's `intensity` is how strong it is, its `confidence` how sure the
recogniser is of it (both 0 to 1; without an intensity, the confidence stands for it). An expression is a Big6
name the client accepts ("happy", "sad", "surprised", "angry", "afraid", "disgusted" or the bare category
names), or "neutral" (logged with no emotion reading: Big6 has none for it). Every utterance gets a reply
`reply_after` seconds later (default 1.5); the driver gives it before replaying the next event, as the
mission answers one utterance at a time.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from semantic_log_generator import EmotionCategory

from segb_server.examples.emotion_mirror.mission import is_neutral

REPLY_AFTER = 1.5


class ScriptError(ValueError):
    """The script file cannot be replayed; the message says where and why."""


@dataclass(frozen=True)
class Expression:
    at: datetime
    expression: str
    confidence: float = 0.9
    intensity: float | None = None


@dataclass(frozen=True)
class Utterance:
    at: datetime
    text: str
    reply_at: datetime


Event = Expression | Utterance


@dataclass(frozen=True)
class Script:
    human_id: str
    human_name: str
    events: list[Event]


# A fixed start, so replaying the default script twice mints the same activity IRIs with the same times
# (the mission numbers its activities by turn, and an activity with two start times would confuse audits).
DEFAULT_SCRIPT: dict[str, Any] = {
    "human": {"id": "maria", "name": "Maria"},
    "start": "2026-03-10T10:00:00Z",
    "events": [
        {"at": 0, "expression": "happy", "intensity": 0.92, "confidence": 0.87},
        {"at": 1, "says": "Hi! I passed my driving test today!"},
        {"at": 10, "expression": "surprised", "intensity": 0.81, "confidence": 0.74},
        {"at": 11, "says": "I did not expect to pass on the first try."},
        {"at": 20, "expression": "sad", "intensity": 0.64, "confidence": 0.58},
        {"at": 21, "says": "I wish my grandmother could have seen it."},
        {"at": 30, "expression": "happy", "intensity": 0.95, "confidence": 0.91},
        {"at": 31, "says": "Anyway, let's celebrate tonight!"},
    ],
}


def default_script() -> Script:
    return parse_script(DEFAULT_SCRIPT)


def load_script(path: Path) -> Script:
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise ScriptError(f"cannot read {path}: {error.strerror}") from None
    except json.JSONDecodeError as error:
        raise ScriptError(f"{path} is not JSON: {error}") from None
    return parse_script(document)


def parse_script(document: Any) -> Script:
    if not isinstance(document, dict):
        raise ScriptError("a script is a JSON object with 'human', 'start' and 'events'")
    human = document.get("human") or {}
    human_id, human_name = human.get("id"), human.get("name")
    if not isinstance(human_id, str) or not human_id or not isinstance(human_name, str) or not human_name:
        raise ScriptError("'human' needs a non-empty 'id' and 'name'")
    start = _start(document.get("start"))
    raw_events = document.get("events")
    if not isinstance(raw_events, list) or not raw_events:
        raise ScriptError("'events' must be a non-empty list")
    events = [_event(index, raw, start) for index, raw in enumerate(raw_events)]
    # The mission links a reply to the last expression seen, so events must be replayed in time order.
    events.sort(key=lambda event: event.at)
    return Script(human_id=human_id, human_name=human_name, events=events)


def _start(value: Any) -> datetime:
    if value is None:
        return datetime.now(UTC).replace(microsecond=0)
    try:
        start = datetime.fromisoformat(str(value))
    except ValueError:
        raise ScriptError(f"'start' is not an ISO 8601 time: {value!r}") from None
    if start.tzinfo is None:
        raise ScriptError("'start' needs a time zone, e.g. 2026-03-10T10:00:00Z")
    return start.astimezone(UTC)


def _event(index: int, raw: Any, start: datetime) -> Event:
    where = f"events[{index}]"
    if not isinstance(raw, dict):
        raise ScriptError(f"{where} must be an object")
    offset = raw.get("at")
    if isinstance(offset, bool) or not isinstance(offset, int | float) or offset < 0:
        raise ScriptError(f"{where}.at must be a number of seconds >= 0")
    at = start + timedelta(seconds=offset)
    if "expression" in raw:
        confidence, intensity = raw.get("confidence", 0.9), raw.get("intensity")
        for name, score in (("confidence", confidence), ("intensity", confidence if intensity is None else intensity)):
            if isinstance(score, bool) or not isinstance(score, int | float) or not 0 <= score <= 1:
                raise ScriptError(f"{where}.{name} must be between 0 and 1")
        expression = str(raw["expression"])
        try:
            if not is_neutral(expression):
                EmotionCategory.coerce(expression)  # refused here, before anything is published
        except ValueError:
            raise ScriptError(f"{where}.expression {expression!r} is not a Big6 emotion or neutral") from None
        strength = None if intensity is None else float(intensity)
        return Expression(at=at, expression=expression, confidence=float(confidence), intensity=strength)
    if "says" in raw:
        reply_after = raw.get("reply_after", REPLY_AFTER)
        if isinstance(reply_after, bool) or not isinstance(reply_after, int | float) or reply_after < 0:
            raise ScriptError(f"{where}.reply_after must be a number of seconds >= 0")
        return Utterance(at=at, text=str(raw["says"]), reply_at=at + timedelta(seconds=reply_after))
    raise ScriptError(f"{where} needs 'expression' or 'says'")
