"""Text a robot wrote can hold Unicode's explicit direction controls (U+202E, right-to-left override, turns
what follows it around on screen). Quoted inside a sentence the server composes — a timeline event, a
finding's message — it would turn the server's own words around too ("…never answered Eve" shown reversed).
Those sentences show each such control as a visible mark instead; the log itself keeps the text as sent."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.in_process import InProcess, publisher_for
from tests.support.settle import settle

OVERRIDE = "\u202e"
ISOLATE = "\u2067"  # right-to-left isolate
NAME, TEXT = f"TIA{OVERRIDE}Go", f"hello {ISOLATE}there"
TURTLE = f"""
@prefix schema: <http://schema.org/> . @prefix prov: <http://www.w3.org/ns/prov#> .
@prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> . @prefix oro: <http://kb.openrobots.org#> .
@prefix foaf: <http://xmlns.com/foaf/0.1/> . @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
<https://e.org/robot> a oro:Robot ; schema:name "{NAME}" .
<https://e.org/eve> a oro:Human ; foaf:firstName "Eve" .
<https://e.org/listen> a segb:LoggedActivity, oro:ListeningEvent ; segb:wasPerformedBy <https://e.org/robot> ;
    prov:startedAtTime "2026-05-02T10:00:00Z"^^xsd:dateTime .
<https://e.org/heard> a schema:Message, oro:InitialMessage ; schema:sender <https://e.org/eve> ;
    schema:text "{TEXT}" ; prov:wasGeneratedBy <https://e.org/listen> .
"""


@pytest.fixture(scope="module")
def served() -> Iterator[InProcess]:
    with InProcess(create_app(make_settings())) as server:
        publisher_for(server.client, "robot").publish_turtle(TURTLE)
        settle(server.client)
        yield server


def test_a_timeline_sentence_shows_a_robots_direction_controls_as_marks(served: InProcess) -> None:
    events = served.get("/timeline", params={"limit": 100, "robot": "https://e.org/robot"}).json()["rows"]
    sentences = [str(event["sentence"]) for event in events]
    said = [sentence for sentence in sentences if "hello" in sentence]
    assert said, sentences
    assert all(OVERRIDE not in sentence and ISOLATE not in sentence for sentence in sentences), sentences
    assert "TIA[U+202E]Go" in " ".join(sentences) and "hello [U+2067]there" in said[0], sentences


def test_a_findings_message_shows_them_as_marks_too(served: InProcess) -> None:
    findings = served.get("/findings", params={"rule": "unanswered-message"}).json()["findings"]
    assert len(findings) == 1, findings
    assert findings[0]["message"] == "TIA[U+202E]Go never answered Eve: “hello [U+2067]there”"


def test_the_log_keeps_the_text_as_the_robot_sent_it(served: InProcess) -> None:
    rows = served.get("/reports/conversations").json()["rows"]
    assert [row["text"] for row in rows] == [TEXT]
