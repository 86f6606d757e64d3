"""A long, dense window of one robot for the timeline's scale test: `events` events in one hour, in the PyPI
client's shapes, as N-Triples for `segb import` — a conversation (a listening activity and the message it heard,
from one visitor, by turns), or state snapshots with a note (three triples an event: the cheapest window to load
and keep)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

BASE = "https://example.org/segb/robots/longshift/v1/"
ROBOT = BASE + "robot_longshift"
HUMAN = BASE + "human_visitor"
START = datetime(2026, 3, 10, 9, 0, 0, tzinfo=UTC)
HOUR = timedelta(hours=1)
P = {
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#", "prov": "http://www.w3.org/ns/prov#",
    "schema": "http://schema.org/", "foaf": "http://xmlns.com/foaf/0.1/",
    "segb": "http://www.gsi.upm.es/ontologies/segb/ns#", "oro": "http://kb.openrobots.org#",
    "xsd": "http://www.w3.org/2001/XMLSchema#",
}  # fmt: skip


def _iri(curie: str) -> str:
    prefix, local = curie.split(":", 1)
    return f"<{P[prefix]}{local}>"


def lines(events: int) -> Iterator[str]:
    """N-Triples of `events` events (half listenings, half the messages they heard), evenly over one hour."""
    a, yes = _iri("rdf:type"), f"<{ROBOT}>"
    yield f"{yes} {a} {_iri('oro:Robot')} ."
    yield f'{yes} {_iri("schema:name")} "Long Shift"@en .'
    yield f"<{HUMAN}> {a} {_iri('oro:Human')} ."
    yield f'<{HUMAN}> {_iri("foaf:firstName")} "Visitor"@en .'
    step = HOUR / max(1, events // 2)
    for turn in range(events // 2):
        activity, message = f"<{BASE}activity_listen_{turn}>", f"<{BASE}message_heard_{turn}>"
        moment = (START + step * turn).isoformat()
        yield f"{activity} {a} {_iri('segb:LoggedActivity')} ."
        yield f"{activity} {a} {_iri('oro:ListeningEvent')} ."
        yield f"{activity} {_iri('segb:wasPerformedBy')} {yes} ."
        yield f'{activity} {_iri("prov:startedAtTime")} "{moment}"^^{_iri("xsd:dateTime")} .'
        yield f"{message} {a} {_iri('schema:Message')} ."
        yield f'{message} {_iri("schema:text")} "Question {turn}: where is room {turn % 400}?"@en .'
        yield f"{message} {_iri('prov:wasGeneratedBy')} {activity} ."
        yield f"{message} {_iri('schema:sender')} <{HUMAN}> ."


def states(events: int) -> Iterator[str]:
    """N-Triples of `events` state snapshots of the robot, evenly over one hour."""
    a, yes = _iri("rdf:type"), f"<{ROBOT}>"
    yield f"{yes} {a} {_iri('oro:Robot')} ."
    yield f'{yes} {_iri("schema:name")} "Long Shift"@en .'
    step = HOUR / max(1, events)
    for turn in range(events):
        state = f"<{BASE}state_{turn}>"
        yield f"{state} {_iri('prov:wasAttributedTo')} {yes} ."
        yield f'{state} {_iri("prov:generatedAtTime")} "{(START + step * turn).isoformat()}"^^{_iri("xsd:dateTime")} .'
        yield f'{state} <http://www.w3.org/2000/01/rdf-schema#comment> "Round {turn} of the ward"@en .'


def write(path: Path, events: int, *, conversation: bool = True) -> Path:
    with path.open("w", encoding="utf-8") as file:
        for line in (lines if conversation else states)(events):
            file.write(line + "\n")
    return path
