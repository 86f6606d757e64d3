"""A robot's posts made by the real PyPI client, through the emotion-mirror robot: the data the tests that need
volume publish (and the bench's workloads, which read them from here).

One interaction (expression seen, utterance heard, reply given) is three events of about 40, 30 and 80 triples.
A robot publishes after every event; the helpers below give each event's delta, a robot's whole graph, copies of
it relabelled as other robots, or deltas with the messages they add.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from pyoxigraph import Literal, RdfFormat, parse
from rdflib import Graph

from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from segb_server.examples.emotion_mirror.publishing import turtle_of

T0 = datetime(2026, 3, 10, 9, 0, tzinfo=UTC)
EXPRESSIONS = ["happy", "sad", "surprised", "angry", "happy", "afraid"]


class RecordingGraph(Graph):
    """An rdflib graph that remembers what was added since the last `take()`: deltas without diffing."""

    def __init__(self) -> None:
        super().__init__()
        self._added: list[tuple] = []

    def add(self, triple):  # type: ignore[no-untyped-def, override]
        if triple not in self:
            self._added.append(triple)
        return super().add(triple)

    def take(self) -> list[tuple]:
        added, self._added = self._added, []
        return added


def mission(robot: str = "mirror") -> EmotionMirrorMission:
    config = RobotConfig(
        robot_id=robot, robot_name=robot.title(), base_namespace=f"https://example.org/segb/robots/{robot}/v1/"
    )
    return EmotionMirrorMission.start(config, human_id=f"{robot}_visitor", human_name="Maria")


def recording_mission(robot: str) -> tuple[EmotionMirrorMission, RecordingGraph]:
    robot_mission = mission(robot)
    recording = RecordingGraph()
    for prefix, namespace in robot_mission.logger.graph.namespaces():
        recording.bind(prefix, namespace, override=True)
    for triple in robot_mission.logger.graph:
        recording.add(triple)
    robot_mission.logger.graph = recording
    return robot_mission, recording


def run_exchange(robot: EmotionMirrorMission, index: int) -> None:
    """One interaction: expression seen, utterance heard, reply given (three events)."""
    at = T0 + timedelta(seconds=20 * index)
    robot.on_face_expression(EXPRESSIONS[index % len(EXPRESSIONS)], at)
    exchange = robot.on_user_utterance(f"Utterance {index}: I passed my driving test!", at + timedelta(seconds=1))
    robot.respond(exchange, at + timedelta(seconds=3))


def turtle(triples: list[tuple], like: Graph) -> str:
    return turtle_of(triples, like)


def event_deltas(count: int, robot_name: str = "mirror") -> list[str]:
    """Turtle of what each event adds, `count` of them (the first also carries robot, human and models)."""
    robot, recording = recording_mission(robot_name)
    payloads = [turtle(recording.take(), recording)]
    index = 0
    while len(payloads) < count:
        at = T0 + timedelta(seconds=20 * index)
        robot.on_face_expression(EXPRESSIONS[index % len(EXPRESSIONS)], at)
        payloads.append(turtle(recording.take(), recording))
        exchange = robot.on_user_utterance(f"Utterance {index}: I passed my test!", at + timedelta(seconds=1))
        payloads.append(turtle(recording.take(), recording))
        robot.respond(exchange, at + timedelta(seconds=3))
        payloads.append(turtle(recording.take(), recording))
        index += 1
    return payloads[:count]


def ntriples_of(interactions: int, robot_name: str) -> str:
    """One robot's whole graph after `interactions` interactions, as N-Triples (for bulk loading)."""
    robot, _ = recording_mission(robot_name)
    for index in range(interactions):
        run_exchange(robot, index)
    return robot.logger.graph.serialize(format="nt")


def replicate(ntriples: str, copies: int, robot_name: str = "mirror") -> Iterator[str]:
    """`copies` relabelled copies of one robot's N-Triples: robot i gets its own namespace, visitor and shared
    events, and its times shift by i days, so report filters and orderings are not degenerate."""
    for copy in range(copies):
        text = ntriples.replace(f"/robots/{robot_name}/", f"/robots/{robot_name}{copy}/")
        # Shared events are keyed by the visitor, so another robot's visitor has events of its own.
        text = text.replace("/segb/shared-events/", f"/segb/shared-events/copy{copy}-")
        if copy:
            text = text.replace("2026-03-10T", f"2026-03-{10 + copy % 18:02d}T")
        yield text


@dataclass(frozen=True)
class LivePost:
    """One event's delta, with the messages it adds and a time at or before every activity it logs (so a
    report filtered `since` it holds its rows)."""

    payload: str
    messages: tuple[str, ...]
    since: str


SCHEMA_MESSAGE = "http://schema.org/Message"
RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
XSD_DATETIME = "http://www.w3.org/2001/XMLSchema#dateTime"
ROBOT_CLASS = "http://kb.openrobots.org#Robot"


def live_posts(count: int, robot_name: str = "live") -> list[LivePost]:
    """`count` event deltas of one robot, each with the IRIs of the messages it adds."""
    posts = []
    for payload in event_deltas(count, robot_name):
        quads = list(parse(payload.encode(), RdfFormat.TURTLE))
        messages = tuple(
            q.subject.value for q in quads if q.predicate.value == RDF_TYPE and q.object.value == SCHEMA_MESSAGE
        )
        times = [
            datetime.fromisoformat(q.object.value)
            for q in quads
            if isinstance(q.object, Literal) and q.object.datatype.value == XSD_DATETIME
        ]
        since = (min(times) - timedelta(minutes=1)).isoformat() if times else T0.isoformat()
        posts.append(LivePost(payload, messages, since))
    return posts


def robot_of(payload: str) -> str:
    """The IRI of the robot a payload describes (its first post names it)."""
    for quad in parse(payload.encode(), RdfFormat.TURTLE):
        if quad.predicate.value == RDF_TYPE and quad.object.value == ROBOT_CLASS:
            return quad.subject.value
    raise ValueError("the payload names no robot")
