"""The bench's own workload: a robot's whole accumulated graph after each interaction, as the client really sends
it. The posts themselves are made by `tests/support/robot_posts.py` (the real PyPI client, through the
emotion-mirror robot), which the tests use too.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from tests.support.robot_posts import recording_mission, run_exchange, turtle


@dataclass(frozen=True)
class CumulativePost:
    interactions: int
    payload: str


def cumulative_posts(interactions: int, robot_name: str = "mirror") -> Iterator[CumulativePost]:
    """After each interaction, the robot's whole graph as one Turtle document.

    The document is the concatenation of every interaction's Turtle delta (repeated @prefix lines are
    valid Turtle): the same triples `logger.serialize()` would send, produced without re-serialising the
    whole graph each time, which would cost the client seconds per post at 100k triples.
    """
    robot, recording = recording_mission(robot_name)
    parts = [turtle(recording.take(), recording)]
    for index in range(interactions):
        run_exchange(robot, index)
        parts.append(turtle(recording.take(), recording))
        yield CumulativePost(index + 1, "".join(parts))
