"""Payloads for the benchmarks, produced by the real PyPI client through the emotion-mirror robot."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta

from rdflib import Graph

from examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig

T0 = datetime(2026, 3, 10, 9, 0, tzinfo=UTC)
EXPRESSIONS = ["happy", "sad", "surprised", "angry", "happy", "afraid"]


def mission(robot: str = "mirror") -> EmotionMirrorMission:
    config = RobotConfig(
        robot_id=robot, robot_name=robot.title(), base_namespace=f"https://example.org/segb/robots/{robot}/v1/"
    )
    return EmotionMirrorMission.start(config, human_id="maria", human_name="Maria")


def run_exchange(robot: EmotionMirrorMission, index: int) -> None:
    """One interaction: expression seen, utterance heard, reply given (three events)."""
    at = T0 + timedelta(seconds=20 * index)
    robot.on_face_expression(EXPRESSIONS[index % len(EXPRESSIONS)], at)
    exchange = robot.on_user_utterance(
        f"Utterance number {index}: I passed my driving test!", at + timedelta(seconds=1)
    )
    robot.respond(exchange, at + timedelta(seconds=3))


def event_deltas(count: int, robot_name: str = "mirror") -> Iterator[str]:
    """Turtle of what each event adds (the reference evaluation's disjoint per-event payloads)."""
    robot = mission(robot_name)
    seen = Graph()
    published: list[str] = []

    def publish(logger) -> None:  # type: ignore[no-untyped-def]
        delta = Graph()
        for prefix, namespace in logger.graph.namespaces():
            delta.bind(prefix, namespace)
        for triple in logger.graph:
            if triple not in seen:
                delta.add(triple)
                seen.add(triple)
        published.append(delta.serialize(format="turtle"))

    robot.publish = publish
    index = 0
    while True:
        while published:
            yield published.pop(0)
            count -= 1
            if count == 0:
                return
        run_exchange(robot, index)
        index += 1


def cumulative_graph(exchanges: int, robot_name: str = "mirror") -> EmotionMirrorMission:
    robot = mission(robot_name)
    for index in range(exchanges):
        run_exchange(robot, index)
    return robot
