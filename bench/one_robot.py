"""One robot that runs for months (examples/receptionist.py): every post is one visit to the same robot node, so
its history never stops growing. The payloads are what the PyPI client `semantic-log-generator` emits for one
visit, made once by the client itself and numbered for each post (a format string), so a bench client can send
hundreds of them a second without spending its own CPU on rdflib. The posts only add children to the robot's
hub: the ones whose upkeep must not grow with it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from rdflib import Graph

from bench.workloads import RecordingGraph
from segb_server.examples.receptionist import log_visit, receptionist

T0 = datetime(2026, 1, 5, 8, 0, tzinfo=UTC)
SECONDS_PER_VISIT = 7  # visits are this far apart in the log's own time
# The numbers made for one visit, replaced by each post's own: a marker index and a marker time.
MARKER = 987654321
MARKER_TIME = datetime(2031, 7, 9, 10, 11, 12, tzinfo=UTC)


@dataclass(frozen=True)
class OneRobot:
    """The robot's first post (the robot and its models) and one visit as a numbered template."""

    first: str  # N-Triples
    visit_template: str  # N-Triples with {i} and the {t0}…{t3} times

    def visit(self, index: int) -> str:
        """Visit `index` (0, 1, …) as N-Triples: its own visitor, event, activities, messages and times."""
        at = T0 + timedelta(seconds=SECONDS_PER_VISIT * index)
        times = {f"t{step}": _lexical(at + timedelta(seconds=step)) for step in range(4)}
        return self.visit_template.format(i=index, **times)

    def history(self, visits: int, start: int = 0) -> str:
        """`visits` visits from `start` as one N-Triples document (for loading a long history at once)."""
        return "".join(self.visit(index) for index in range(start, start + visits))


def one_robot() -> OneRobot:
    """The first post and the visit template, made by the real client."""
    logger = receptionist()
    recording = RecordingGraph()
    for prefix, namespace in logger.graph.namespaces():
        recording.bind(prefix, namespace, override=True)
    for triple in logger.graph:
        recording.add(triple)
    logger.graph = recording
    first = _ntriples(recording.take())
    log_visit(logger, MARKER, MARKER_TIME)
    return OneRobot(first, _template(_ntriples(recording.take())))


def _ntriples(triples: list[tuple]) -> str:  # type: ignore[type-arg]
    graph = Graph()
    for triple in triples:
        graph.add(triple)
    return graph.serialize(format="nt")


def _template(ntriples: str) -> str:
    """The marker visit with its numbers as fields: the marker index, the marker's times (whole seconds from
    the marker time), and the shared event's digest (which the client derives from them)."""
    text = ntriples.replace("{", "{{").replace("}", "}}")
    text = re.sub(r"human_utterance_[0-9a-f]{8,}", f"human_utterance_{MARKER}", text)
    for step in range(4):
        text = text.replace(_lexical(MARKER_TIME + timedelta(seconds=step)), f"{{t{step}}}")
    return text.replace(str(MARKER), "{i}")


def _lexical(moment: datetime) -> str:
    """A whole-second time as the client writes it (rdflib normalises to +00:00, no fraction)."""
    return moment.isoformat()
