"""A robot's name or text can hold Unicode's explicit direction controls (U+202E, right-to-left override, turns what
follows it around on screen, the page's own words included). Every page the server renders shows each such control
as a visible mark (`[U+202E]`): the person's export page, the conversation's header and bubbles on the reports,
the workbench's answer, the timeline file and an evidence bundle's page; only the query the viewer typed is given
back as typed."""

from __future__ import annotations

import io
import re
import zipfile
from collections.abc import Iterator
from urllib.parse import quote

import pytest

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.in_process import UiOverApi, publisher_for
from tests.support.settle import settle

OVERRIDE, ISOLATE = "\u202e", "\u2067"  # right-to-left override, right-to-left isolate
CONTROLS = re.compile("[\u202a-\u202e\u2066-\u2069]")
ROBOT_NAME, HUMAN_NAME, SAID = f"TIA{OVERRIDE}Go", f"Eve{ISOLATE}", f"hello {OVERRIDE}there"
LABEL = f"listening {OVERRIDE}to Eve"
EVE = "https://e.org/eve"
TURTLE = f"""
@prefix schema: <http://schema.org/> . @prefix prov: <http://www.w3.org/ns/prov#> .
@prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> . @prefix oro: <http://kb.openrobots.org#> .
@prefix foaf: <http://xmlns.com/foaf/0.1/> . @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
<https://e.org/robot> a oro:Robot ; schema:name "{ROBOT_NAME}" .
<{EVE}> a oro:Human ; foaf:firstName "{HUMAN_NAME}" .
<https://e.org/listen> a segb:LoggedActivity, oro:ListeningEvent ; segb:wasPerformedBy <https://e.org/robot> ;
    prov:startedAtTime "2026-05-02T10:00:00Z"^^xsd:dateTime ; rdfs:label "{LABEL}" .
<https://e.org/heard> a schema:Message, oro:InitialMessage ; schema:sender <{EVE}> ;
    schema:text "{SAID}" ; prov:wasGeneratedBy <https://e.org/listen> .
"""


@pytest.fixture(scope="module")
def served() -> Iterator[UiOverApi]:
    with UiOverApi(create_app(make_settings()), make_settings()) as server:
        publisher_for(server.api, "robot").publish_turtle(TURTLE)
        settle(server.api)
        yield server


def page(served: UiOverApi, path: str, **params: str) -> str:
    answer = served.get(path, params=params)
    assert answer.status_code == 200, answer.text
    return answer.text


def test_the_person_export_page_shows_direction_controls_as_marks(served: UiOverApi) -> None:
    exported = served.api.get(f"/humans/{quote(EVE, safe='')}/export", params={"format": "html"})
    assert exported.status_code == 200, exported.text
    assert CONTROLS.findall(exported.text) == []
    assert "Eve[U+2067] said to TIA[U+202E]Go: “hello [U+202E]there”" in exported.text
    assert "<h1>What the robots' log holds about Eve[U+2067]</h1>" in exported.text
    relayed = page(served, "/people/export", iri=EVE, format="html")  # the UI's people page opens the same
    assert CONTROLS.findall(relayed) == [] and "TIA[U+202E]Go" in relayed


def test_the_conversation_header_and_bubbles_show_them_as_marks(served: UiOverApi) -> None:
    for path in ("/reports", "/reports/conversations"):
        html = page(served, path)
        assert CONTROLS.findall(html) == [], path
        header = re.search(r'class="thread-title">(.*?)</h\d>', html, re.DOTALL)
        assert header is not None, path
        assert "TIA[U+202E]Go" in header[1] and "Eve[U+2067]" in header[1], header[1]
        assert "hello [U+202E]there" in html, path


def test_every_page_showing_robot_text_shows_the_marks(served: UiOverApi) -> None:
    pages = {
        "/people": {},
        "/timeline": {"robot": "https://e.org/robot"},
        "/findings": {},
        "/explain": {"iri": "https://e.org/heard"},
        "/reports/participants": {},
    }
    for path, params in pages.items():
        html = page(served, path, **params)
        assert CONTROLS.findall(html) == [], path
        assert "[U+202E]" in html or "[U+2067]" in html, path


def test_the_workbench_shows_the_answer_with_marks_and_the_query_as_typed(served: UiOverApi) -> None:
    query = f'SELECT ?text WHERE {{ ?m <http://schema.org/text> ?text FILTER(CONTAINS(?text, "{OVERRIDE}")) }}'
    html = page(served, "/query", query=query)
    editor = re.search(r'<textarea[^>]*id="query-editor"[^>]*>(.*?)</textarea>', html, re.DOTALL)
    assert editor is not None and OVERRIDE in editor[1]  # the viewer's query, to run again unchanged
    answer = html.replace(editor[0], "")
    assert CONTROLS.findall(answer) == [] and "hello [U+202E]there" in answer


def test_the_timeline_file_and_the_evidence_page_show_them_as_marks(served: UiOverApi) -> None:
    timeline = served.api.get("/timeline", params={"robot": "https://e.org/robot", "format": "html"})
    assert timeline.status_code == 200, timeline.text
    assert CONTROLS.findall(timeline.text) == [] and "TIA[U+202E]Go" in timeline.text
    bundle = served.api.get("/evidence", params={"robot": "https://e.org/robot"})
    assert bundle.status_code == 200, bundle.text
    with zipfile.ZipFile(io.BytesIO(bundle.content)) as archive:
        page_names = [name for name in archive.namelist() if name.endswith("timeline.html")]
        assert len(page_names) == 1, archive.namelist()
        evidence = archive.read(page_names[0]).decode("utf-8")
    assert CONTROLS.findall(evidence) == [] and "listening [U+202E]to Eve" in evidence
