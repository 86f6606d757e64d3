"""Why did the robot do that? The causal chain around one message, activity, emotion, state or shared event.

From the seed (the activity it stands for: itself, the one that produced it, or for a shared event the activities
about it), the walk goes upstream along the provenance links that say where an activity came from
(`segb:triggeredByActivity`, `segb:triggeredByEntity`, the activity that generated a triggering message,
`prov:wasDerivedFrom`: the rule of reading `CAUSE_LINKS`) for its causes, and downstream along the same links for its
effects; what the walk then meets beside them (another cause of an effect, an activity about the same shared event)
is related, neither cause nor effect, whatever its time. Each activity is told as one step of a story in time order:
who performed it, what was heard or said, which models it used, which emotions it read, which shared event and
human it was about. Who spoke, whether an emotion was read on someone or expressed, and an activity's kind are the
rules of reading (backend/reading.py). Nodes are read with `GraphService.summaries`, a batch at a time (every node
the walk may read next): from the graph index, which keeps the links and the literals told here (`TOLD_LITERALS`), so
an explanation costs a few indexed SQLite queries whatever the size or load of the store; from the store (two bound
queries a batch) while the index is first built.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from segb_server.backend.reading import (
    CAUSE_LINKS,
    DERIVED_FROM,
    HEARD_MESSAGE,
    INFORMED_BY,
    TRIGGERED_BY_ACTIVITY,
    TRIGGERED_BY_ENTITY,
    activity_kind,
    speaker,
    target_kind,
)
from segb_server.backend.reading import GENERATED_BY as WAS_GENERATED_BY
from segb_server.backend.reading import INTERMEDIATE_ACTIVITY as INTERMEDIATE
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.graph.facts import normal_time
from segb_server.backend.services.graph.service import GraphService, local_name
from segb_server.backend.vocabulary import PERFORMED_BY, PREFIXES

SEGB, PROV, SCHEMA, ORO = PREFIXES["segb"], PREFIXES["prov"], PREFIXES["schema"], PREFIXES["oro"]
ONYX, OA, MLS, SOSA = PREFIXES["onyx"], PREFIXES["oa"], PREFIXES["mls"], PREFIXES["sosa"]
RDFS = PREFIXES["rdfs"]

PRODUCED = SEGB + "producedEntityResult"
GENERATED = PROV + "generated"
USED_MODEL = SEGB + "usedMLModel"
ABOUT = SCHEMA + "about"
SENDER = SCHEMA + "sender"
HAS_EMOTION = ONYX + "hasEmotion"
HAS_TARGET = OA + "hasTarget"

FEATURE_OF_INTEREST = SOSA + "hasFeatureOfInterest"
# The only links the walk follows backwards: a robot, human or model is the object of a link from each of its
# activities (hundreds of thousands after a month), and none of those is read to tell a story.
FOLLOWED_INCOMING = frozenset({PRODUCED, GENERATED, HAS_EMOTION, FEATURE_OF_INTEREST, *CAUSE_LINKS})
# The literals a story tells besides names and times (which the graph index keeps anyway).
TOLD_LITERALS = frozenset({
    RDFS + "label", SCHEMA + "text", SCHEMA + "version", ONYX + "hasEmotionIntensity", ONYX + "algorithmConfidence",
})  # fmt: skip
MAX_ACTIVITIES = 40
MAX_DEPTH = 6
PREFETCH = 80  # resources read in one batch at most
RDF_TYPE = PREFIXES["rdf"] + "type"  # its objects are classes: never read to tell a story


@dataclass
class Resource:
    """One node as `GraphService.resource` returns it, with quick access by predicate."""

    body: dict[str, Any]

    @property
    def iri(self) -> str:
        return self.body["iri"]

    @property
    def kind(self) -> str:
        return self.body["kind"]

    @property
    def label(self) -> str:
        return self.body["label"]

    def out(self, predicate: str) -> list[str]:
        return [str(s["value"]) for s in self.body["outgoing"] if s["predicate"] == predicate]

    def into(self, predicate: str) -> list[str]:
        return [str(s["value"]) for s in self.body["incoming"] if s["predicate"] == predicate]

    def literal(self, predicate: str) -> Any:
        return next((s["value"] for s in self.body["outgoing"] if s["predicate"] == predicate), None)

    def types(self) -> set[str]:
        return set(self.out(PREFIXES["rdf"] + "type"))


@dataclass
class Step:
    activity: str
    time: str | None
    kind: str
    robot: dict[str, str] | None
    label: str | None
    role: str = "context"
    sentence: str = ""
    heard: list[dict[str, Any]] = field(default_factory=list)
    said: list[dict[str, Any]] = field(default_factory=list)
    models: list[dict[str, Any]] = field(default_factory=list)
    emotions: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    triggered_by: list[str] = field(default_factory=list)
    triggered_by_named: list[dict[str, str]] = field(default_factory=list)  # the same, each with a display name


class ExplainService:
    def __init__(self, graph: GraphService) -> None:
        self.graph = graph

    def explain(self, iri: str) -> dict[str, Any]:
        """The story around `iri`; blocking (store I/O)."""
        reader = _Reader(self.graph)
        seed = reader.get(iri)
        if not seed.body["outgoing"]:  # perhaps only literals the summary leaves out: the store decides
            known = self.graph.resource(iri, incoming_limit=1)
            if not known["outgoing"] and not known["incoming"]:
                raise NotFound(f"Nothing is known about <{iri}>.")
        seed_activities = reader.activities_of(seed)
        roles = self._walk(reader, seed_activities)
        steps = [reader.step(activity) for activity in roles]
        for step in steps:
            step.role = roles[step.activity]
        steps.sort(key=lambda step: (step.time or "~", step.activity))
        return {
            "iri": iri,
            "seed": {"iri": seed.iri, "label": self._seed_label(reader, seed), "kind": seed.kind, "time": _time(seed)},
            "steps": [step.__dict__ for step in steps],
            "truncated": len(roles) >= MAX_ACTIVITIES,
        }

    @staticmethod
    def _seed_label(reader: _Reader, seed: Resource) -> str:
        return reader.activity_name(seed.iri) if seed.kind == "activity" else seed.label

    def _walk(self, reader: _Reader, seeds: list[str]) -> dict[str, str]:
        """Each activity of the story with its role: "seed", "cause" (upstream of a seed along the provenance
        links), "effect" (downstream), or "related" (reached through both directions: another cause of an
        effect, an effect of a cause)."""
        roles = dict.fromkeys(seeds, "seed")
        for role, follow in (("cause", reader.causes), ("effect", reader.effects)):
            self._spread(roles, seeds, role, follow)
        self._spread(roles, list(roles), "related", lambda iri: reader.causes(iri) + reader.effects(iri))
        return roles

    @staticmethod
    def _spread(roles: dict[str, str], start: list[str], role: str, follow: Callable[[str], list[str]]) -> None:
        depth = dict.fromkeys(start, 0)
        queue = deque(start)
        while queue and len(roles) < MAX_ACTIVITIES:
            current = queue.popleft()
            if depth[current] >= MAX_DEPTH:
                continue
            for neighbour in follow(current):
                if neighbour not in depth and len(roles) < MAX_ACTIVITIES:
                    depth[neighbour] = depth[current] + 1
                    roles.setdefault(neighbour, role)
                    queue.append(neighbour)


class _Reader:
    """Resource lookups for one explanation, each node read once. A node not read yet is read together with
    every node the ones already read link to (the walk's next steps, most likely), so an explanation costs a
    round trip to the store per step of its walk rather than per node."""

    def __init__(self, graph: GraphService) -> None:
        self.graph = graph
        self.pending = graph.on_the_way()  # read once for the whole walk, and before any of the index
        self.cache: dict[str, Resource] = {}
        self.linked: dict[str, None] = {}  # IRIs the nodes read so far link to, not read yet (in order)

    def get(self, iri: str) -> Resource:
        if iri not in self.cache:
            batch = [iri, *(linked for linked in self.linked if linked != iri)][:PREFETCH]
            for body in self.graph.summaries(batch, self.pending, incoming=FOLLOWED_INCOMING).values():
                self._add(Resource(body))
        return self.cache[iri]

    def _add(self, node: Resource) -> None:
        self.cache[node.iri] = node
        self.linked.pop(node.iri, None)
        statements = [s for s in node.body["outgoing"] if s["predicate"] != RDF_TYPE] + node.body["incoming"]
        for statement in statements:
            value = statement["value"]
            if not statement["is_literal"] and isinstance(value, str) and value not in self.cache:
                self.linked[value] = None

    def activities_of(self, node: Resource) -> list[str]:
        """The activity a seed stands for: itself, the activity that produced it, or for a shared event the
        activities about it (each robot's that sensed it)."""
        if node.kind == "activity":
            return [node.iri]
        if node.kind == "shared-event":
            return self.about(node.iri) or [node.iri]
        producers = node.out(WAS_GENERATED_BY) + node.into(PRODUCED) + node.into(GENERATED)
        if not producers:
            for annotation in node.into(HAS_EMOTION):  # an onyx:Emotion: through its annotation
                producers += self.get(annotation).into(PRODUCED) + self.get(annotation).into(GENERATED)
        return list(dict.fromkeys(producers)) or [node.iri]

    def about(self, event: str) -> list[str]:
        """The activities about a shared event. `schema:about` is read backwards here only, not on every node: a
        human is the object of one from each shared event about them."""
        body = self.graph.summaries([event], self.pending, incoming={ABOUT})[event]
        return [iri for iri in Resource(body).into(ABOUT) if self.get(iri).kind == "activity"]

    def produced(self, activity: str) -> list[str]:
        node = self.get(activity)
        return list(dict.fromkeys(node.out(PRODUCED) + node.out(GENERATED) + node.into(WAS_GENERATED_BY)))

    def causes(self, activity: str) -> list[str]:
        """Upstream along the rule of reading's cause links: what triggered or informed it, what made the entities
        it was triggered by, what made the entities its results derive from."""
        node = self.get(activity)
        found = node.out(TRIGGERED_BY_ACTIVITY) + node.out(INTERMEDIATE) + node.out(INFORMED_BY)
        for entity in node.out(TRIGGERED_BY_ENTITY):
            found += self.activities_of(self.get(entity))
        for entity in self.produced(activity):
            for previous in self.get(entity).out(DERIVED_FROM):
                found += self.activities_of(self.get(previous))
        return [iri for iri in dict.fromkeys(found) if iri != activity]

    def effects(self, activity: str) -> list[str]:
        """Downstream along the same links (`causes` read the other way)."""
        node = self.get(activity)
        found = node.into(TRIGGERED_BY_ACTIVITY) + node.into(INTERMEDIATE) + node.into(INFORMED_BY)
        for entity in self.produced(activity):
            produced = self.get(entity)
            found += produced.into(TRIGGERED_BY_ENTITY)
            for later in produced.into(DERIVED_FROM):
                found += self.activities_of(self.get(later))
        return [iri for iri in dict.fromkeys(found) if iri != activity]

    def activity_name(self, activity: str) -> str:
        """An activity as a reader names it: its robot's name and its label (or kind), never its IRI."""
        node = self.get(activity)
        performers = node.out(PERFORMED_BY)
        what = node.literal(RDFS + "label") or activity_kind(node.types()).replace("-", " ")
        return f"{self.get(performers[0]).label}: {what}" if performers else str(what)

    def name(self, iri: str) -> dict[str, str]:
        return {"iri": iri, "label": self.get(iri).label}

    def step(self, activity: str) -> Step:
        node = self.get(activity)
        types = node.types()
        kind = activity_kind(types)
        performers = node.out(PERFORMED_BY)
        step = Step(
            activity=activity,
            time=_time(node),
            kind=kind,
            robot=self.name(performers[0]) if performers else None,
            label=node.literal(RDFS + "label"),
            triggered_by=self.causes(activity),
        )
        step.triggered_by_named = [{"iri": cause, "label": self.activity_name(cause)} for cause in step.triggered_by]
        listening = ORO + "ListeningEvent" in types
        produced = [self.get(entity) for entity in self.produced(activity)]
        for entity in produced:
            self._add_result(step, entity, listening)
        if step.time is None:  # an activity logged without a time happened when what it produced did
            step.time = min(filter(None, (_time(entity) for entity in produced)), default=None)
        for model in node.out(USED_MODEL):
            described = self.get(model)
            step.models.append({**self.name(model), "version": described.literal(SCHEMA + "version")})
        for event in node.out(ABOUT):
            step.events.append(self._event(event))
        step.sentence = sentence(step)
        return step

    def _add_result(self, step: Step, entity: Resource, listening: bool) -> None:
        if entity.kind == "message":
            senders = entity.out(SENDER)
            sender = self.name(senders[0]) if senders else None
            message = {
                "iri": entity.iri,
                "text": entity.literal(SCHEMA + "text"),
                "sender": sender,
                # The rule of reading for an event's time: its own, else its activity's
                "time": _time(entity) or step.time,
            }
            robot_said = self._said_by_robot(entity, senders, step.robot, listening)
            (step.said if robot_said else step.heard).append(message)
        elif entity.kind == "emotion":
            targets = [self.name(t) for t in entity.out(HAS_TARGET)]
            expressed = bool(targets) and all(self._is_self(step, target["iri"]) for target in targets)
            for emotion_iri in entity.out(HAS_EMOTION):
                emotion = self.get(emotion_iri)
                category = emotion.out(ONYX + "hasEmotionCategory")
                step.emotions.append({
                    "iri": emotion_iri,
                    "category": local_name(category[0]).removeprefix("big6_") if category else None,
                    "intensity": emotion.literal(ONYX + "hasEmotionIntensity"),
                    "confidence": emotion.literal(ONYX + "algorithmConfidence"),
                    "targets": targets,
                    "expressed": expressed,
                })  # fmt: skip

    def _said_by_robot(
        self, message: Resource, senders: list[str], robot: dict[str, str] | None, listening: bool
    ) -> bool:
        """Whether the robot said it, by the rule of reading `speaker` (the conversations report's and the
        timeline's too), read over the explanation's resources."""
        kinds = {sender: self.get(sender).kind for sender in senders}
        performer = robot["iri"] if robot is not None else None
        return speaker(kinds, performer, HEARD_MESSAGE in message.types(), listening) == "robot"

    def _is_self(self, step: Step, target: str) -> bool:
        """Whether an emotion on `target` is the robot's own, expressed (the rule of reading `target_kind`)."""
        performer = step.robot["iri"] if step.robot is not None else None
        return target_kind(target, self.get(target).kind, performer) == "robot"

    def _event(self, event: str) -> dict[str, Any]:
        node = self.get(event)
        humans = [self.name(h) for h in node.out(ABOUT) if self.get(h).kind == "human"]
        modalities = []
        for observation in node.into(FEATURE_OF_INTEREST):
            for procedure in self.get(observation).out(SOSA + "usedProcedure"):
                modalities.append(self.get(procedure).label)
        return {"iri": event, "label": node.label, "humans": humans, "modalities": sorted(set(modalities))}


def _time(node: Resource) -> str | None:
    """A node's own time, in UTC as every page writes it."""
    time = node.body.get("time")
    return normal_time(str(time)) if time else None


def _quote(text: object) -> str:
    return f"“{text}”"


def sentence(step: Step) -> str:
    """One line of the story, e.g. `Maria said “I passed” (heard by ARI via speech)`.

    A model is named only beside what it did: with the emotions read when the activity's result was an
    analysis, with the reply when the activity spoke. An emotion the robot expressed about itself is
    "expressed", never "analysed": no model read it."""
    robot = step.robot["label"] if step.robot else "Someone"
    modalities = sorted({m for event in step.events for m in event["modalities"]})
    via = f" via {', '.join(modalities)}" if modalities else ""
    models = ", ".join(f"{m['label']} {m['version']}".strip() if m.get("version") else m["label"] for m in step.models)
    using = f" with {models}" if models else ""
    analysed = [e for e in step.emotions if not e.get("expressed")]
    expressed = [e for e in step.emotions if e.get("expressed")]
    parts: list[str] = []
    for message in step.heard:
        who = message["sender"]["label"] if message["sender"] else "An unidentified speaker"
        parts.append(f"{who} said {_quote(message['text'])} (heard by {robot}{via})")
    if analysed:
        parts.append(f"{robot} analysed emotion{'' if step.said else using}: {_readings(analysed, on=True)}")
    elif step.kind == "decision":
        parts.append(f"{robot} decided {step.label or 'what to do'}{using}")
    for message in step.said:
        parts.append(f"{robot} said {_quote(message['text'])}{using}")
    if expressed:
        parts.append(f"{robot} expressed {_readings(expressed, on=False)}")
    if not parts:
        humans = [h["label"] for event in step.events for h in event["humans"]]
        if step.kind == "human-detection" and humans:
            parts.append(f"{robot} detected {', '.join(humans)}{via}")
        else:
            parts.append(f"{robot}: {step.label or step.kind}{using}")
    return " · ".join(parts)


def _readings(emotions: list[dict[str, Any]], *, on: bool) -> str:
    return "; ".join(
        f"{e['category']} {e['intensity']}"
        + (f" on {', '.join(t['label'] for t in e['targets'])}" if on and e["targets"] else "")
        for e in emotions
    )
