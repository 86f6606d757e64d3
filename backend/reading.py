"""The one reading of the log: each rule that turns a robot's triples into a statement a page makes, written once.

Every report, timeline kind, audit rule, person export, evidence window and erasure is a `.rq` file, and every
Python reader (explanations, the graph's labels and times, the offline check) reads these rules from here. A
`.rq` file asks for a rule by name where its patterns go, e.g.

    %speaker(?message, ?activity, ?robot, ?speaker)
    %concerned-human(?message, ?activity, ?human)
    %event-time(?message, ?activity, ?time)
    %display-name(?human, ?humanName)

and the catalog expands each call into SPARQL (`expand`) when it loads the file, so the text a store runs, the
reports' planner keeps current and `/reports` shows is plain SPARQL 1.1. Why rules expanded into each query
rather than derived statements kept in a graph of their own: a derived statement would be a second copy of
what a robot said (a name, a time) that erasure must find and the evidence bundles must leave out, and a second
upkeep beside the reports' own; an expanded rule is read where the triples are, so a page, a finding and a
bundle can only disagree if the rule itself is wrong, and then they are wrong together and fixed in one place.

The rules (README, "One reading of the log", lists each with its file):
- what is a human, a robot, an agent: `vocabulary.PERSON_CLASSES`, `vocabulary.ROBOT_CLASSES` (`kind_of`);
- an agent's display name: `NAME_PREDICATES`, the first one it has;
- an event's time: `TIME_PREDICATES` of the node itself, else of the activity behind it;
- who spoke a message: `speaker`;
- which human a message or event concerns: `concerned-human`;
- an emotion read on someone or expressed by the robot: `target_kind`;
- whether a human's utterance was answered: `unanswered` (by any robot that heard it, through its shared event);
- whether an activity involves a human: `involves-human`;
- cause and effect between two events: `CAUSE_LINKS`, followed upstream for causes, downstream for effects.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection
from typing import Literal as TypingLiteral

from segb_server.backend.vocabulary import PERSON_CLASSES, PREFIXES, ROBOT_CLASSES

_PROV, _SCHEMA, _SEGB, _ORO = PREFIXES["prov"], PREFIXES["schema"], PREFIXES["segb"], PREFIXES["oro"]

# An agent's display name: the first of these it has. A robot's client names robots with schema:name and humans
# with foaf:firstName; robots that write their own Turtle often use rdfs:label.
NAME_PREDICATES: tuple[str, ...] = (_SCHEMA + "name", PREFIXES["foaf"] + "firstName", PREFIXES["rdfs"] + "label")

# An event's time: the first of these the node itself has (an activity's start, a state's or a message's own
# generation time), else the first its generating activity has.
TIME_PREDICATES: tuple[str, ...] = (_PROV + "startedAtTime", _PROV + "endedAtTime", _PROV + "generatedAtTime")

# Who spoke: a message typed as heard input (a human's words as the robot logged them).
HEARD_MESSAGE = _ORO + "InitialMessage"
LISTENING = _ORO + "ListeningEvent"
RESPONSE = _ORO + "ResponseAction"

# Cause and effect: an event's causes are upstream along these links (the subject came from the object), its
# effects downstream. Events that only share a shared event are related, neither cause nor effect.
CAUSE_LINKS: tuple[str, ...] = (
    _SEGB + "triggeredByActivity",
    _SEGB + "triggeredByEntity",
    _SEGB + "intermediateActivity",
    _PROV + "used",
    _PROV + "wasGeneratedBy",
    _PROV + "wasDerivedFrom",
    _PROV + "wasInformedBy",
)

# An activity's kind by its types, most specific first: the client types an activity that logged emotions
# onyx:EmotionAnalysis whatever else it is, so that type comes last.
ACTIVITY_KINDS: tuple[tuple[str, str], ...] = (
    (_ORO + "ResponseAction", "response"),
    (_ORO + "ListeningEvent", "listening"),
    (_ORO + "DecisionMakingAction", "decision"),
    (_ORO + "DetectedHumanEvent", "human-detection"),
    (_ORO + "EmotionRecognitionEvent", "emotion-recognition"),
    (PREFIXES["mls"] + "Run", "ml-run"),
    (PREFIXES["onyx"] + "EmotionAnalysis", "emotion-analysis"),
)

Speaker = TypingLiteral["human", "robot", "unidentified"]
TargetKind = TypingLiteral["human", "robot", "other"]


# --- the rules in Python, for the readers that hold resources rather than run a query -------------------------


def display_name(literals: dict[str, str]) -> str | None:
    """The display name among a resource's literals by predicate, or None when it has no name."""
    return next((literals[predicate] for predicate in NAME_PREDICATES if predicate in literals), None)


def own_time(literals: dict[str, str]) -> str | None:
    """A node's own time among its literals by predicate, or None (then it borrows its activity's)."""
    return next((literals[predicate] for predicate in TIME_PREDICATES if predicate in literals), None)


def activity_kind(types: Collection[str]) -> str:
    """An activity's most specific kind, or "activity"."""
    return next((kind for cls, kind in ACTIVITY_KINDS if cls in types), "activity")


def speaker(sender_kinds: dict[str, str], robot: str | None, marked_heard: bool, by_listening: bool) -> Speaker:
    """Who spoke a message: a human sender; else the robot that performed its activity when it sent it, or when
    the log names no sender and does not mark the message as heard (typed oro:InitialMessage, or produced by a
    listening activity); else someone the log does not identify, never the robot that only heard it.
    `sender_kinds` maps each sender the message names to its kind (`vocabulary.kind_of`)."""
    if "human" in sender_kinds.values():
        return "human"
    if robot is not None and robot in sender_kinds:
        return "robot"
    if not sender_kinds and not marked_heard and not by_listening:
        return "robot"
    return "unidentified"


def target_kind(target: str, target_is: str, performer: str | None) -> TargetKind:
    """An emotion reading's target: "robot" when the robot expressed it about itself (the target is the robot
    that performed the activity; with no performer known, any robot), "human" when it was read on a human,
    else "other". `target_is` is the target's kind (`vocabulary.kind_of`)."""
    if (performer is not None and target == performer) or (performer is None and target_is == "robot"):
        return "robot"
    return "human" if target_is == "human" else "other"


# --- the rules in SPARQL: `%rule(?a, ?b)` in a .rq file -----------------------------------------------------


def _iri(iri: str) -> str:
    return f"<{iri}>"


def _classes(classes: Collection[str]) -> str:
    return ", ".join(_iri(iri) for iri in sorted(classes))


def _human(x: str) -> str:
    """`x` is typed as a person (as a join: Virtuoso 7 lets robots through a FILTER EXISTS on the type)."""
    return f"{x} a {x}_humanClass . FILTER ({x}_humanClass IN ({_classes(PERSON_CLASSES)}))"


def _robot(x: str) -> str:
    return f"{x} a {x}_robotClass . FILTER ({x}_robotClass IN ({_classes(ROBOT_CLASSES)}))"


def _display_name(x: str, name: str) -> str:
    """The name through a key that is always bound: an OPTIONAL on an unbound `x` would pair the row with every
    named resource in the store. One OPTIONAL a predicate (not a path `a|b|c`, which Virtuoso 7 plans badly
    inside OPTIONAL: 37 s against 0.23 s at a million triples)."""
    key = f"{name}_key"
    lines = [f"BIND (COALESCE({x}, <urn:segb:nobody>) AS {key})"]
    names = []
    for index, predicate in enumerate(NAME_PREDICATES):
        lines.append(f"OPTIONAL {{ {key} {_iri(predicate)} {name}_{index} }}")
        names.append(f"{name}_{index}")
    lines.append(f"BIND (COALESCE({', '.join(names)}) AS {name})")
    return "\n  ".join(lines)


def _time_parts(node: str, activity: str, time: str) -> tuple[list[str], list[str]]:
    """The OPTIONALs that read a node's own times and its activity's, and the variables they bind, best first."""
    lines, found = [], []
    sources = [node] if node == activity else [node, activity]
    for source_index, source in enumerate(sources):
        for index, predicate in enumerate(TIME_PREDICATES):
            if source != node and predicate == _PROV + "generatedAtTime":
                continue  # an activity's generation time is not when it happened
            variable = f"{time}_{source_index}{index}"
            lines.append(f"OPTIONAL {{ {source} {_iri(predicate)} {variable} }}")
            found.append(variable)
    return lines, found


def _event_time(node: str, activity: str, time: str) -> str:
    """`time`: the node's own time, else its activity's (unbound when neither has one)."""
    lines, found = _time_parts(node, activity, time)
    lines.append(f"BIND (COALESCE({', '.join(found)}) AS {time})")
    return "\n  ".join(lines)


def _timed_event(node: str, activity: str, time: str) -> str:
    """As `event-time`, keeping only events with a time. Tested on the OPTIONALs' values, not on `time`:
    Virtuoso 7 skips a FILTER on a BIND's result once VALUES are bound."""
    lines, found = _time_parts(node, activity, time)
    lines.append(f"FILTER ({' || '.join(f'BOUND({variable})' for variable in found)})")
    lines.append(f"BIND (COALESCE({', '.join(found)}) AS {time})")
    return "\n  ".join(lines)


def _speaker(message: str, activity: str, robot: str, speaker: str) -> str:
    """`speaker`'s rule (above) in SPARQL. Told from OPTIONAL matches, not EXISTS in a BIND (which Virtuoso 7
    answers wrongly in a SELECT DISTINCT), and before any BIND that coalesces a sender: after one, Virtuoso 7
    takes it as bound in a group that opens with VALUES."""
    s = speaker
    return "\n  ".join([
        f"OPTIONAL {{ {message} <{_SCHEMA}sender> {s}_human . {_human(s + '_human')} }}",
        f"OPTIONAL {{ {message} <{_SCHEMA}sender> {s}_robot . FILTER ({s}_robot = {robot}) }}",
        f"OPTIONAL {{ {message} <{_SCHEMA}sender> {s}_named . BIND (true AS {s}_hasSender) }}",
        f"OPTIONAL {{ {message} a <{HEARD_MESSAGE}> . BIND (true AS {s}_heard) }}",
        f"OPTIONAL {{ {activity} a <{LISTENING}> . BIND (true AS {s}_listening) }}",
        f"BIND (IF(BOUND({s}_human), \"human\", IF(BOUND({s}_robot), \"robot\",",
        f"      IF(!BOUND({s}_hasSender) && !BOUND({s}_heard) && !BOUND({s}_listening), \"robot\", \"unidentified\")))"
        f" AS {s})",
    ])  # fmt: skip


def _concerned_human(message: str, activity: str, human: str) -> str:
    """The human a message belongs to: who sent it, else the sender of the message it answers, else the human
    its shared event is about, else the human its activity's shared event is about — never every human present."""
    h = human
    about = f"<{_SCHEMA}about>"
    return "\n  ".join([
        f"OPTIONAL {{ {message} <{_SCHEMA}sender> {h}_sender . {_human(h + '_sender')} }}",
        f"OPTIONAL {{ {message} <{_PROV}wasDerivedFrom> {h}_previous . {h}_previous <{_SCHEMA}sender> {h}_answered ."
        f" {_human(h + '_answered')} }}",
        f"OPTIONAL {{ {message} <{_PROV}specializationOf> {h}_event . {h}_event {about} {h}_subject ."
        f" {_human(h + '_subject')} }}",
        f"OPTIONAL {{ {activity} {about} {h}_activityEvent . {h}_activityEvent {about} {h}_activitySubject ."
        f" {_human(h + '_activitySubject')} }}",
        f"BIND (COALESCE({h}_sender, {h}_answered, {h}_subject, {h}_activitySubject) AS {h})",
    ])  # fmt: skip


def _unanswered(focus: str, heard: str, human: str) -> str:
    """The human's utterance `focus` (heard by activity `heard`) was answered by no robot: no reply derived from
    it, nor from the same utterance as another robot heard it (a message the same human sent, heard by an
    activity about the same shared event), generated by a response activity triggered by what it answers. One
    pattern a group, each in the EXISTS of the one before: the embedded store plans a group of patterns in an
    EXISTS from the pattern with the most constants whatever the query has bound, which read the robot's whole
    history for each message (18 ms a message at 2,000 visits of one robot); alone in its group, a pattern is
    read with what is bound."""
    about, derived, generated = f"<{_SCHEMA}about>", f"<{_PROV}wasDerivedFrom>", f"<{_PROV}wasGeneratedBy>"

    def replied(message: str, reply: str) -> str:
        return (
            f"{reply} {derived} {message} . FILTER EXISTS {{ {reply} {generated} {reply}_response ."
            f" FILTER EXISTS {{ {reply}_response <{_SEGB}triggeredByEntity> {message} ."
            f" FILTER EXISTS {{ {reply}_response a <{RESPONSE}> }} }} }}"
        )

    same = f"{focus}_same"
    return "\n  ".join([
        f"FILTER NOT EXISTS {{ {replied(focus, focus + '_reply')} }}",
        f"FILTER NOT EXISTS {{ {heard} {about} {focus}_event .",
        f"    FILTER EXISTS {{ {same}Heard {about} {focus}_event .",
        f"    FILTER EXISTS {{ {same} {generated} {same}Heard . FILTER ({same} != {focus})",
        f"    FILTER EXISTS {{ {same} <{_SCHEMA}sender> {human} .",
        f"    FILTER EXISTS {{ {replied(same, same + '_reply')} }} }} }} }} }}",
    ])  # fmt: skip


def _activity_kind(activity: str, kind: str) -> str:
    """`activity_kind` in SPARQL, as one value (IF over EXISTS: not in a SELECT DISTINCT, which Virtuoso 7
    answers wrongly with EXISTS in a BIND; there, use `activity-kinds`)."""
    chain = '"activity"'
    for cls, name in reversed(ACTIVITY_KINDS):
        chain = f'IF(EXISTS {{ {activity} a <{cls}> }}, "{name}", {chain})'
    return f"BIND ({chain} AS {kind})"


def _activity_kinds(activity: str, kind: str) -> str:
    """Each of the activity's kinds, a row each (the most specific is first in `ACTIVITY_KINDS`). Not a UNION of
    BINDs: asked for several activities at once, Virtuoso 7 gives one activity the kinds of another."""
    pairs = " ".join(f'(<{cls}> "{name}")' for cls, name in ACTIVITY_KINDS)
    return f"OPTIONAL {{ {activity} a {kind}_class . VALUES ({kind}_class {kind}) {{ {pairs} }} }}"


def _involves_human(activity: str) -> str:
    """The `human` parameter's filter of an activity: it was about a shared event about them, heard or said a
    message they sent or about such an event, read an emotion on them, or what they said triggered it."""
    h = "?param_human"
    exists = [
        f"{activity} <{_SCHEMA}about>/<{_SCHEMA}about> {h}",
        f"{activity}_involved <{_PROV}wasGeneratedBy> {activity} ; <{_SCHEMA}sender> {h}",
        f"{activity}_involved <{_PROV}wasGeneratedBy> {activity} ; <{_PROV}specializationOf>/<{_SCHEMA}about> {h}",
        f"{activity} <{_SEGB}producedEntityResult>/<{PREFIXES['oa']}hasTarget> {h}",
        f"{activity} <{_SEGB}triggeredByEntity>/<{_SCHEMA}sender> {h}",
    ]
    return f"FILTER (!BOUND({h}) || " + " || ".join(f"EXISTS {{ {body} }}" for body in exists) + ")"


def _target_kind(target: str, robot: str, kind: str) -> str:
    """`target_kind`'s rule in SPARQL, from OPTIONAL matches (EXISTS in a BIND is answered wrongly by
    Virtuoso 7 in a SELECT DISTINCT)."""
    return "\n  ".join([
        f"OPTIONAL {{ {_robot(target)} BIND (true AS {kind}_robot) }}",
        f"OPTIONAL {{ {_human(target)} BIND (true AS {kind}_human) }}",
        f"BIND (IF((BOUND({robot}) && {target} = {robot}) || (!BOUND({robot}) && BOUND({kind}_robot)), \"robot\",",
        f"      IF(BOUND({kind}_human), \"human\", \"other\")) AS {kind})",
    ])  # fmt: skip


RULES: dict[str, Callable[..., str]] = {
    "human": _human,
    "robot": _robot,
    "display-name": _display_name,
    "event-time": _event_time,
    "timed-event": _timed_event,
    "speaker": _speaker,
    "concerned-human": _concerned_human,
    "unanswered": _unanswered,
    "involves-human": _involves_human,
    "activity-kind": _activity_kind,
    "activity-kinds": _activity_kinds,
    "target-kind": _target_kind,
}
_CALL = re.compile(r"%([a-z][a-z-]*)\(([^()]*)\)")
_VARIABLE = re.compile(r"\?[A-Za-z_][A-Za-z0-9_]*")


class ReadingError(ValueError):
    """A `.rq` file calls a rule that does not exist, or with the wrong arguments."""


def expand(text: str) -> str:
    """The query with each `%rule(?a, ?b)` replaced by the rule's SPARQL (comment lines are left as they are)."""
    lines = []
    for line in text.splitlines():
        lines.append(line if line.lstrip().startswith("#") else _CALL.sub(_expand_call, line))
    return "\n".join(lines) + ("\n" if text.endswith("\n") else "")


def _expand_call(match: re.Match[str]) -> str:
    name, arguments = match.group(1), [part.strip() for part in match.group(2).split(",")]
    rule = RULES.get(name)
    if rule is None:
        raise ReadingError(f"%{name}: no such rule of reading (known: {', '.join(sorted(RULES))})")
    if not all(_VARIABLE.fullmatch(argument) for argument in arguments):
        raise ReadingError(f"%{name}: arguments must be variables, got {match.group(2)!r}")
    try:
        return rule(*arguments)
    except TypeError:
        raise ReadingError(f"%{name}: wrong number of arguments ({len(arguments)})") from None
