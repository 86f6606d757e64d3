"""One honest line per timeline event, from the rows of its query (the only place the timeline's wording lives).

The explanation page's rules (services/explain/service.py) hold here too: a model is named only beside the
activity that used it; an emotion a robot logs about itself is *expressed*, one it logs about a human is
*read*; a message without a human sender that the log marks as heard was said by an unidentified speaker,
never by the robot that heard it (the conversations report's `speaker`). Names come from the log; where it
has none, the end of the IRI stands in. What a robot wrote (texts, labels) is quoted as it wrote it, on one
line; pages escape it.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from segb_server.backend.reading import ACTIVITY_KINDS
from segb_server.backend.services import direction_controls
from segb_server.backend.services.graph.service import local_name
from segb_server.backend.services.values import JsonValue

Rows = Sequence[dict[str, JsonValue]]


@dataclass(frozen=True)
class Told:
    sentence: str
    robot: str | None  # the robot (or other performer) the event is of, when it has one
    humans: list[str]  # the humans the sentence names


def tell(kind: str, rows: Rows) -> Told:
    """The sentence of one event of `kind` from its rows (several when it has several targets, models, …), a
    robot's direction controls shown as marks (`direction_controls.py`)."""
    told = TELLERS[kind](rows)
    return replace(told, sentence=direction_controls.shown(told.sentence))


# --- pieces ------------------------------------------------------------------------------------------------

_SPACES = re.compile(r"\s+")


def _text(value: JsonValue) -> str:
    """A value a robot wrote, on one line."""
    return _SPACES.sub(" ", str(value)).strip()


def _quoted(value: JsonValue) -> str:
    return f"“{_text(value)}”"


def _name(row: dict[str, JsonValue], iri: str, name: str) -> str:
    """What the log calls the resource in column `iri`: its name, else its IRI's end."""
    named = row.get(name)
    if named not in (None, ""):
        return _text(named)
    value = row.get(iri)
    return local_name(str(value)) if value else "Someone"


def _number(value: JsonValue) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    return "true" if value is True else "false" if value is False else _text(value)


def _listed(items: Sequence[str]) -> str:
    items = list(dict.fromkeys(items))
    if len(items) <= 2:
        return " and ".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def _with_label(sentence: str, label: JsonValue) -> str:
    return f"{sentence} ({_text(label)})" if label not in (None, "") else sentence


def _humans(rows: Rows, iri: str = "human", name: str = "humanName") -> dict[str, str]:
    """The humans the rows name (IRI → name), in order."""
    return {str(row[iri]): _name(row, iri, name) for row in rows if row.get(iri)}


def _performer(rows: Rows) -> tuple[str | None, str]:
    first = rows[0]
    robot = first.get("robot")
    return (str(robot) if robot else None), _name(first, "robot", "robotName")


# --- one teller per kind -----------------------------------------------------------------------------------


def _shared_event(rows: Rows) -> Told:
    humans = _humans(rows)
    description = next((row["description"] for row in rows if row.get("description")), None)
    sentence = "Shared event" + (f" about {_listed(list(humans.values()))}" if humans else "")
    if description is not None:
        sentence += f": {_quoted(description)}"
    return Told(sentence, None, list(humans))


def _perception(rows: Rows) -> Told:
    robot, name = _performer(rows)
    humans = _humans(rows)
    about = _listed(list(humans.values()))
    if any(row.get("perceived") == "human-detection" for row in rows):
        sentence = f"{name} detected {about}" if humans else f"{name} logged a human detection"
    else:
        sentence = f"{name} ran emotion recognition" + (f" about {about}" if humans else "")
    return Told(_with_label(sentence, rows[0].get("label")), robot, list(humans))


def _activity_kind(verb: str) -> Callable[[Rows], Told]:
    def told(rows: Rows) -> Told:
        robot, name = _performer(rows)
        return Told(_with_label(f"{name} {verb}", rows[0].get("label")), robot, [])

    return told


def _decision(rows: Rows) -> Told:
    robot, name = _performer(rows)
    label = rows[0].get("label")
    return Told(f"{name} decided {_text(label) if label not in (None, '') else 'what to do'}", robot, [])


# An activity's kind as words, the most specific of its types first (the explanation page's order). The client
# types every activity that logged an emotion annotation onyx:EmotionAnalysis, a robot's own expressed emotion
# included: such an activity logged emotions, it is not told as an analysis (no model read an expressed emotion).
KIND_WORDS = {
    "response": "response",
    "listening": "listening",
    "decision": "decision",
    "human-detection": "human detection",
    "emotion-recognition": "emotion recognition",
    "ml-run": "model run",
    "emotion-analysis": "emotion annotation",
}


def _kind_words(rows: Rows) -> str:
    kinds = {row.get("activityKind") for row in rows}
    return next((KIND_WORDS[kind] for _, kind in ACTIVITY_KINDS if kind in kinds), "activity")


def _other_activity(rows: Rows) -> Told:
    robot, name = _performer(rows)
    label = rows[0].get("label")
    if label not in (None, ""):
        return Told(f"{name}: {_text(label)}", robot, [])
    kind = _kind_words(rows)
    return Told(f"{name} logged {'an' if kind[0] in 'aeiou' else 'a'} {kind}", robot, [])


def _model(rows: Rows) -> Told:
    robot, name = _performer(rows)
    models = []
    for row in rows:  # a row per model and kind of the activity
        version = row.get("version")
        models.append(_name(row, "model", "modelName") + (f" {_text(version)}" if version not in (None, "") else ""))
    first = rows[0]
    sentence = f"{name} used {_listed(models)}"
    return Told(_with_label(sentence, first.get("label") or _kind_words(rows)), robot, [])


def _observation(rows: Rows) -> Told:
    robot, name = _performer(rows)
    label = rows[0].get("label")
    sentence = f"{name} observed {_quoted(label)}" if label not in (None, "") else f"{name} logged an observation"
    return Told(sentence, robot, [])


def _message(rows: Rows) -> Told:
    robot, name = _performer(rows)
    first = rows[0]
    text = _quoted(first.get("text"))
    speaker = first.get("speaker")
    human = first.get("human")
    humans = [str(human)] if human else []
    if speaker == "robot":
        return Told(f"{name} said {text}", robot, humans)
    if speaker == "human":
        sent = next((row for row in rows if row.get("sender") == human), first)
        who = _name(sent, "sender", "senderName") if sent.get("sender") else _name(first, "human", "humanName")
    else:
        # Heard from someone the log names but who is no human (another robot, say), or from no one it names.
        others = [row for row in rows if row.get("sender") and row.get("sender") != first.get("robot")]
        who = _name(others[0], "sender", "senderName") if others else "An unidentified speaker"
    return Told(f"{who} said {text} (heard by {name})", robot, humans)


def _emotion(rows: Rows) -> Told:
    robot, name = _performer(rows)
    first = rows[0]
    reading = _text(first.get("category"))
    if first.get("intensity") is not None:
        reading += f" {_number(first['intensity'])}"
    if robot is not None:
        expressed = all(row.get("target") == robot for row in rows)
    else:  # no known performer: a robot target is the robot itself, as the explanation page tells it
        expressed = all(row.get("targetKind") == "robot" for row in rows)
    humans = [str(row["target"]) for row in rows if row.get("targetKind") == "human"]
    if expressed:
        return Told(f"{name} expressed {reading}", robot, humans)
    targets = _listed([_name(row, "target", "targetName") for row in rows])
    confidence = first.get("confidence")
    sentence = f"{name} read {reading} on {targets}"
    if confidence is not None:
        sentence += f" (confidence {_number(confidence)})"
    return Told(sentence, robot, humans)


def _state(rows: Rows) -> Told:
    robot, name = _performer(rows)
    first = rows[0]
    parts = []
    if first.get("location"):
        parts.append(f"at {local_name(str(first['location']))}")
    for row in rows:
        if row.get("property") is None:
            continue
        unit = row.get("unit")
        shown = " %" if unit == "PERCENT" else f" {_text(unit)}" if unit not in (None, "") else ""
        parts.append(f"{_text(row['property'])} {_number(row.get('value'))}{shown}")
    if first.get("note") not in (None, ""):
        parts.append(f"note {_quoted(first['note'])}")
    sentence = f"{name}'s state: {', '.join(dict.fromkeys(parts))}" if parts else f"{name} logged a state"
    return Told(sentence, robot, [])


TELLERS: dict[str, Callable[[Rows], Told]] = {
    "shared-event": _shared_event,
    "perception": _perception,
    "listening": _activity_kind("listened"),
    "decision": _decision,
    "response": _activity_kind("responded"),
    "activity": _other_activity,
    "model": _model,
    "observation": _observation,
    "message": _message,
    "emotion": _emotion,
    "state": _state,
}
