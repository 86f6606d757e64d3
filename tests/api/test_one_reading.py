"""One reading of the log: every page states what the rules of reading (backend/reading.py) say, and no two pages
state one fact differently. The corpus: the PyPI client's shapes (the demo: ARI and TIAGo, one utterance of Maria's
heard by both and answered by ARI) and a robot that writes its own Turtle (tests/fixtures/reading/own-turtle.ttl:
humans typed foaf:Person or prov:Person only, names by schema:name or rdfs:label, times on the messages themselves),
with a speaker link that arrives in a later post. Each test runs on the embedded store and on a real Virtuoso."""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store
from segb_server.ui.log_preview import read_log
from tests.conftest import make_settings
from tests.support.in_process import InProcess, UiOverApi
from tests.support.settle import settle

CORPUS = Path(__file__).resolve().parents[1] / "fixtures" / "reading"
G = "https://example.org/greeter/"
TIAGO_HEARD = "https://example.org/segb/robots/tiago/v1/message_user_1"
TURTLE = {"Content-Type": "text/turtle"}


@pytest.fixture
def corpus(store: Store) -> Iterator[InProcess]:
    """The demo (the real client's log of two robots) and the robot writing its own Turtle, in one store."""
    with InProcess(create_app(make_settings(), store=store, demo=True)) as served:
        answer = served.client.post("/ttl", content=(CORPUS / "own-turtle.ttl").read_bytes(), headers=TURTLE)
        assert answer.status_code == 201, answer.text
        settle(served.client)
        yield served


def rows(served: InProcess, path: str, **params: str) -> list[dict[str, Any]]:
    answer = served.client.get(path, params={"limit": "1000", **params})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    return body["rows"] if "rows" in body else body["findings"]


def conversation(served: InProcess) -> dict[str, dict[str, Any]]:
    return {row["message"]: row for row in rows(served, "/reports/conversations")}


def test_a_robot_writing_its_own_turtle_reads_as_the_rules_say(corpus: InProcess) -> None:
    said = conversation(corpus)
    told = {
        iri.removeprefix(G): (row["speaker"], row["time"], row["human"], row["humanName"], row["robotName"])
        for iri, row in said.items()
        if iri.startswith(G)
    }
    assert told == {
        # A human typed foaf:Person, named by schema:name; the message's own time, its activity has none
        "question_1": ("human", "2026-04-01T10:00:00Z", G + "ana", "Ana", "Greeter"),
        # A human typed prov:Person, named by rdfs:label; a robot named by rdfs:label
        "question_2": ("human", "2026-04-01T10:01:00Z", G + "ben", "Ben", "Greeter"),
        "answer_2": ("robot", "2026-04-01T10:01:03Z", G + "ben", "Ben", "Greeter"),
    }
    (anger,) = [row for row in rows(corpus, "/reports/emotion-timeline") if row["emotion"] == G + "emotion_1"]
    assert (anger["targetKind"], anger["targetName"], anger["robotName"]) == ("human", "Ana", "Greeter")

    found = {(f["rule"], f["focus"]): f for f in rows(corpus, "/findings") if f["focus"].startswith(G)}
    unanswered = found[("unanswered-message", G + "question_1")]
    assert (unanswered["human"], unanswered["time"]) == (G + "ana", "2026-04-01T10:00:00Z")
    assert unanswered["message"] == "Greeter never answered Ana: “Where is the pharmacy?”"
    assert ("unanswered-message", G + "question_2") not in found  # the robot answered Ben
    assert found[("strong-negative-emotion", G + "emotion_1")]["human"] == G + "ana"

    timeline = {row["iri"]: row for row in rows(corpus, "/timeline", robot=G + "robot") if row["kind"] == "message"}
    assert timeline[G + "question_1"]["sentence"] == "Ana said “Where is the pharmacy?” (heard by Greeter)"
    assert timeline[G + "question_1"]["humans"] == [G + "ana"]
    emotions = [row for row in rows(corpus, "/timeline", human=G + "ana") if row["kind"] == "emotion"]
    assert [row["sentence"] for row in emotions] == ["Greeter read anger 0.9 on Ana"]

    nodes = {node["id"]: node for node in corpus.client.get("/graph").json()["nodes"]}
    assert [(nodes[G + name]["label"], nodes[G + name]["kind"]) for name in ("robot", "ana", "ben")] == [
        ("Greeter", "robot"), ("Ana", "human"), ("Ben", "human")
    ]  # fmt: skip


def test_an_utterance_heard_by_two_robots_and_answered_by_one_is_answered(corpus: InProcess) -> None:
    """TIAGo overheard what Maria said to ARI; ARI answered it: no finding, and it is Maria's on every page."""
    assert not [f for f in rows(corpus, "/findings", rule="unanswered-message") if not f["focus"].startswith(G)]
    heard = conversation(corpus)[TIAGO_HEARD]
    assert (heard["speaker"], heard["humanName"], heard["robotName"]) == ("human", "Maria", "TIAGo")


def test_a_speaker_named_in_a_later_post_changes_every_page(corpus: InProcess) -> None:
    overheard = f"""@prefix prov: <http://www.w3.org/ns/prov#> . @prefix schema: <http://schema.org/> .
        @prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> . @prefix oro: <http://kb.openrobots.org#> .
        @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
        <{G}listen_3> a segb:LoggedActivity, oro:ListeningEvent ; segb:wasPerformedBy <{G}robot> ;
            prov:startedAtTime "2026-04-01T10:05:00+00:00"^^xsd:dateTime .
        <{G}overheard_3> a schema:Message ; schema:text "Any news?"@en ; prov:wasGeneratedBy <{G}listen_3> ."""
    assert corpus.client.post("/ttl", content=overheard, headers=TURTLE).status_code == 201
    settle(corpus.client)

    def pages() -> tuple[object, ...]:
        row = conversation(corpus)[G + "overheard_3"]
        (line,) = [r for r in rows(corpus, "/timeline", robot=G + "robot") if r["iri"] == G + "overheard_3"]
        story = corpus.client.get("/explain", params={"iri": G + "overheard_3"}).json()
        seed = next(step for step in story["steps"] if step["role"] == "seed")
        return row["speaker"], row["humanName"], line["sentence"], seed["sentence"]

    assert pages() == (
        "unidentified", None, "An unidentified speaker said “Any news?” (heard by Greeter)",
        "An unidentified speaker said “Any news?” (heard by Greeter)",
    )  # fmt: skip
    later = f"<{G}overheard_3> <http://schema.org/sender> <{G}ana> ."
    assert corpus.client.post("/ttl", content=later, headers=TURTLE).status_code == 201
    settle(corpus.client)
    assert pages() == (
        "human", "Ana", "Ana said “Any news?” (heard by Greeter)", "Ana said “Any news?” (heard by Greeter)"
    )  # fmt: skip


# --- agreement: every page's statement of one fact, side by side --------------------------------------------------


def statements(served: InProcess) -> dict[tuple[str, str], dict[str, object]]:
    """(message, fact) → {page: what that page states}: speaker, time, human and the human's name, from the
    conversations report, the timeline, the findings, the explanation and the graph."""
    stated: dict[tuple[str, str], dict[str, object]] = defaultdict(dict)
    said = conversation(served)
    for iri, row in said.items():
        for fact in ("speaker", "time", "human", "humanName"):
            stated[(iri, fact)]["conversations"] = row[fact]
    for robot in {row["robot"] for row in said.values()}:
        for line in rows(served, "/timeline", robot=robot):
            if line["kind"] == "message":
                stated[(line["iri"], "time")]["timeline"] = line["time"]
                stated[(line["iri"], "human")]["timeline"] = (line["humans"] or [None])[0]
            elif line["kind"] == "finding" and line["iri"] in said:
                stated[(line["iri"], "time")]["timeline finding"] = line["time"]
    for finding in rows(served, "/findings"):
        if finding["focus"] in said and finding["human"] is not None:
            stated[(finding["focus"], "human")][f"finding {finding['rule']}"] = finding["human"]
            stated[(finding["focus"], "time")][f"finding {finding['rule']}"] = finding["time"]
    nodes = {node["id"]: node for node in served.client.get("/graph", params={"limit": "5000"}).json()["nodes"]}
    for iri in said:
        if iri in nodes and "time" in nodes[iri]:
            stated[(iri, "time")]["graph"] = nodes[iri]["time"]
        story = served.client.get("/explain", params={"iri": iri}).json()
        for step in story["steps"]:
            for role, messages in (("robot", step["said"]), ("heard", step["heard"])):
                for message in messages:
                    if message["iri"] != iri:
                        continue
                    stated[(iri, "time")]["explain"] = message["time"]
                    spoke = "robot" if role == "robot" else said[iri]["speaker"]
                    stated[(iri, "speaker")]["explain"] = spoke if role == "robot" or spoke != "robot" else "heard"
                    if said[iri]["speaker"] == "human":
                        stated[(iri, "humanName")]["explain"] = (message["sender"] or {}).get("label")
    return stated


def disagreements(stated: dict[tuple[str, str], dict[str, object]]) -> list[str]:
    return [
        f"{iri} {fact}: {pages}"
        for (iri, fact), pages in sorted(stated.items())
        if len(set(map(str, pages.values()))) > 1
    ]


def test_no_two_pages_state_one_fact_differently(corpus: InProcess) -> None:
    stated = statements(corpus)
    assert disagreements(stated) == []
    # Each fact of the own-Turtle robot's question is stated by several pages (what the comparison compares)
    assert len(stated[(G + "question_1", "time")]) >= 4 and len(stated[(G + "question_1", "human")]) >= 3
    # …and the comparison tells a page that says otherwise
    stated[(G + "question_1", "time")]["graph"] = "2026-04-01T10:00:02Z"
    assert disagreements(stated) == [f"{G}question_1 time: {stated[(G + 'question_1', 'time')]}"]


def test_the_ui_names_a_previewed_subject_by_the_servers_rule(memory_api: InProcess) -> None:
    """The web UI holds no rule of its own: it reads the name predicates, best first, from GET /vocabulary."""
    names = tuple(memory_api.client.get("/vocabulary").json()["name_predicates"])
    log = f'<{G}robot> <http://www.w3.org/2000/01/rdf-schema#label> "greeter-7" ; <http://schema.org/name> "Greeter" .'
    preview = read_log(log, names)
    assert preview is not None and [subject.name for subject in preview.subjects] == ["Greeter"]


def test_the_people_page_lists_every_human_the_rule_names(tmp_path: Path) -> None:
    """The People page asks for humans by the server's classes and names (GET /vocabulary): a foaf:Person named by
    schema:name and a prov:Person named by rdfs:label are listed, by name, beside the real client's humans."""
    settings = make_settings()
    with UiOverApi(create_app(settings, demo=True), settings) as served:
        answer = served.api.post("/ttl", content=(CORPUS / "own-turtle.ttl").read_bytes(), headers=TURTLE)
        assert answer.status_code == 201
        page = served.client.get("/people")
        assert page.status_code == 200
        listed = re.findall(r"<tr><td>([^<]*)</td><td><code>([^<]+)</code></td>", page.text)
    shown = {iri: name for name, iri in listed}
    assert {shown.get(G + "ana"), shown.get(G + "ben")} == {"Ana", "Ben"}, page.text[:2000]
    assert "Maria" in shown.values() and "Carlos" in shown.values()


def test_an_explanation_follows_provenance_not_the_clock(memory_api: InProcess) -> None:
    """Causes are upstream along the provenance links (triggered by, generated by, informed by), effects
    downstream, whatever their times; what is met only through both directions is related."""
    log = f"""@prefix prov: <http://www.w3.org/ns/prov#> . @prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> .
        @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
        <{G}sense> a segb:LoggedActivity ; segb:wasPerformedBy <{G}robot> ;
            prov:startedAtTime "2026-04-01T10:00:05+00:00"^^xsd:dateTime .
        <{G}reading> prov:wasGeneratedBy <{G}sense> .
        <{G}plan> a segb:LoggedActivity ; segb:wasPerformedBy <{G}robot> ; segb:triggeredByEntity <{G}reading> ;
            prov:startedAtTime "2026-04-01T10:00:03+00:00"^^xsd:dateTime .
        <{G}act> a segb:LoggedActivity ; segb:wasPerformedBy <{G}robot> ; prov:wasInformedBy <{G}plan> ;
            prov:startedAtTime "2026-04-01T10:00:01+00:00"^^xsd:dateTime .
        <{G}other> a segb:LoggedActivity ; segb:wasPerformedBy <{G}robot> ;
            prov:startedAtTime "2026-04-01T10:00:09+00:00"^^xsd:dateTime .
        <{G}act> prov:wasInformedBy <{G}other> ."""
    assert memory_api.client.post("/ttl", content=log, headers=TURTLE).status_code == 201
    settle(memory_api.client)
    story = memory_api.client.get("/explain", params={"iri": G + "plan"}).json()
    roles = {step["activity"].removeprefix(G): step["role"] for step in story["steps"]}
    # `sense` is later than `plan` yet caused it; `act` is earlier yet came of it; `other` only shares an effect
    assert roles == {"sense": "cause", "plan": "seed", "act": "effect", "other": "related"}
