"""No page shows a logged resource by its id: on the demo and the example robot's log, in real headless Chromium,
the explain page of each kind of resource, the graph's node details (nodes clicked in the drawing, and nodes whose
neighbours are not drawn), the shared-context page and the findings name what they show; IRIs stay in links and
tooltips."""

from __future__ import annotations

import re
from typing import Any

import httpx
import pytest

from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, visit

pytestmark = pytest.mark.browser

PREFIXES = """PREFIX oro: <http://kb.openrobots.org#>
PREFIX schema: <http://schema.org/>
PREFIX amor: <http://www.gsi.upm.es/ontologies/amor/ns#>
PREFIX mls: <http://www.w3.org/ns/mls#>
PREFIX segb: <http://www.gsi.upm.es/ontologies/segb/ns#>
"""
# Resources of each kind an auditor opens the explain page of, a few of each (several robots' where there are).
EXPLAINED = {
    "heard message": "?resource a oro:InitialMessage",
    "emotion recognition": "?resource a oro:EmotionRecognitionEvent",
    "listening": "?resource a oro:ListeningEvent",
    "shared event": "?resource a schema:Event",
    "emotion annotation": "?resource a amor:EmotionAnnotation",
    "state": "?resource a segb:Result . FILTER (CONTAINS(STR(?resource), '/state_'))",
    "implementation": "?resource a mls:Implementation",
}
# A 32-hex digest, a shortened one (`6a4f3999…`), a robot's or a human's local name.
DIGEST = re.compile(r"[0-9a-f]{32}|\b[0-9a-f]{8,}…|\b(?:human|robot)_\w+", re.IGNORECASE)


def sparql(stack: UiStack, query: str) -> list[dict[str, str]]:
    answer = httpx.get(
        f"{stack.api_url}/sparql",
        params={"query": PREFIXES + query},
        headers={"Accept": "application/sparql-results+json"},
        timeout=30,
    )
    return [{name: term["value"] for name, term in row.items()} for row in answer.json()["results"]["bindings"]]


@pytest.fixture(scope="module")
def logged_ids(demo_stack: UiStack) -> re.Pattern[str]:
    """Ids as they could be shown: the local name of any resource the robots logged (`message_user_2`,
    `state_state_2`, `activity_recognise_emotion_1`), a digest, or a shortened one. Vocabulary terms are left
    out: `oro:Human` is a name."""
    vocabulary = httpx.get(f"{demo_stack.api_url}/vocabulary", timeout=30).json()["prefixes"].values()
    subjects = [row["s"] for row in sparql(demo_stack, "SELECT DISTINCT ?s WHERE { ?s ?p ?o FILTER isIRI(?s) }")]
    logged = {iri for iri in subjects if not iri.startswith(tuple(vocabulary))}
    tails = {re.split(r"[/#]", iri.rstrip("/#"))[-1] for iri in logged}
    assert {"message_user_2", "state_state_2", "human_maria", "activity_listen_2"} <= tails
    words = "|".join(re.escape(tail) for tail in sorted(tails, key=len, reverse=True))
    return re.compile(rf"{DIGEST.pattern}|(?<![\w-])(?:{words})(?![\w-])", re.IGNORECASE)


def ids_in(page: Any, selector: str, ids: re.Pattern[str]) -> list[str]:
    return sorted({match.group(0) for match in ids.finditer(page.locator(selector).inner_text())})


def test_the_check_finds_every_kind_of_id(logged_ids: re.Pattern[str]) -> None:
    seen = "state_state_2 · Triggered by: 6a4f3999…, e6cf8dce… · activity_recognise_emotion_1 · message_user_2"
    assert len(logged_ids.findall(seen)) == 5
    assert logged_ids.findall("ARI's state at 10:00:03.500 · ARI: Listen to the user · Types: oro:Human") == []


@pytest.mark.parametrize("kind", list(EXPLAINED))
def test_explain_names_each_kind_of_resource(
    demo_stack: UiStack, open_at: Any, logged_ids: re.Pattern[str], kind: str
) -> None:
    resources = [row["resource"] for row in sparql(demo_stack, f"SELECT ?resource WHERE {{ {EXPLAINED[kind]} }}")]
    by_robot = {re.sub(r"[^/#]*$", "", iri): iri for iri in sorted(resources)}  # one per namespace
    page = open_at("desktop")
    for iri in sorted(by_robot.values())[:3]:
        visit(page, f"{demo_stack.ui_url}/explain?" + str(httpx.QueryParams({"iri": iri})))
        assert page.locator(".story-step").count() >= 1, iri
        assert ids_in(page, "main", logged_ids) == [], iri
        assert ids_in(page, ".lead strong", logged_ids) == [], iri  # what the story is about, by name
        for link in page.locator(".story-step a[href^='/explain']").all():
            assert link.get_attribute("title").startswith(("http://", "https://")), iri  # the IRI on hover
    assert axe_violations(page) == []
    assert page.console_errors == []


def test_explain_tells_a_shared_event_by_the_robots_that_sensed_it(demo_stack: UiStack, open_at: Any) -> None:
    event = sparql(
        demo_stack,
        "SELECT ?event (COUNT(DISTINCT ?activity) AS ?n) (GROUP_CONCAT(DISTINCT ?name; separator='|') AS ?robots)"
        " WHERE { ?event a schema:Event . ?activity schema:about ?event ; segb:wasPerformedBy/schema:name ?name }"
        " GROUP BY ?event ORDER BY DESC(?n) ?event LIMIT 1",
    )[0]
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/explain?" + str(httpx.QueryParams({"iri": event["event"]})))
    seeds = page.locator(".story-step.role-seed")  # each activity about it, not the event as an activity
    assert seeds.count() == int(event["n"])
    robots = {re.sub(r".* · by (.+?) · .*", r"\1", meta) for meta in seeds.locator(".story-meta").all_inner_texts()}
    assert robots == set(event["robots"].split("|")) and len(robots) >= 2
    assert seeds.locator(".story-sentence:has-text('(heard by ')").count() == len(robots)


GRAPH_NODES = {  # a node of each kind, as the drawing labels it
    "robot": "ARI",
    "human": "Maria (ARI, TIAGo)",
    "message": "Hi! I passed my driving test today!",
    "state": "TIAGo's state at 10:01:03.500",
    "emotion": "ARI's emotion at 10:00:00",
    "shared-event": "I wish my grandmother could have seen it.",
}
CLICK_NODE = """(id) => {
  const cy = document.getElementById('graph')._cyreg.cy;
  const node = cy.getElementById(id);
  cy.zoom(Math.max(cy.zoom(), 1.5));
  cy.center(node);
  const at = node.renderedPosition(), box = document.getElementById('graph').getBoundingClientRect();
  return { x: box.left + at.x, y: box.top + at.y };
}"""


@pytest.mark.parametrize("kind", list(GRAPH_NODES))
def test_graph_node_details_name_the_node_and_its_neighbours(
    demo_stack: UiStack, open_at: Any, logged_ids: re.Pattern[str], kind: str
) -> None:
    drawn = httpx.get(f"{demo_stack.ui_url}/kg-graph/data", timeout=30).json()["nodes"]
    iri = next(node["id"] for node in drawn if node["kind"] == kind and node["label"] == GRAPH_NODES[kind])
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    page.check("#graph-show-other")
    at = page.evaluate(CLICK_NODE, iri)
    page.mouse.click(at["x"], at["y"])
    page.wait_for_selector(f'#graph-panel[data-iri="{iri}"] table')
    assert ids_in(page, "#graph-panel", logged_ids) == []
    links = page.locator("#graph-panel td a")
    assert links.count() >= 1
    assert all(link.get_attribute("title").startswith(("http://", "https://")) for link in links.all())
    assert axe_violations(page) == []
    assert page.console_errors == []


def test_graph_node_details_name_neighbours_the_drawing_does_not_hold(
    demo_stack: UiStack, open_at: Any, logged_ids: re.Pattern[str]
) -> None:
    drawn = httpx.get(f"{demo_stack.ui_url}/kg-graph/data", timeout=30).json()["nodes"]
    robot = next(node["id"] for node in drawn if node["kind"] == "robot" and node["label"] == "ARI")
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph?" + str(httpx.QueryParams({"focus": robot, "depth": "0"})))
    page.fill("#graph-search-input", "ARI")
    page.click("#graph-search button")
    page.wait_for_selector(f'#graph-panel[data-iri="{robot}"] table')
    shown = page.locator("#graph-panel td a").all_inner_texts()
    assert "ARI's state at 10:00:03.500" in shown and "I am here with you. Tell me more." in shown
    assert ids_in(page, "#graph-panel", logged_ids) == []
    assert page.console_errors == []


def test_shared_context_names_contexts_left_without_a_case(
    demo_stack: UiStack, open_at: Any, logged_ids: re.Pattern[str]
) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/shared-context")
    assert page.locator(".review").count() >= 1
    assert ids_in(page, "main", logged_ids) == []
    page.locator("button.reject").first.click()  # keep apart: the context stays ambiguous, with no case
    page.wait_for_selector("text=Ambiguous without a case")
    assert ids_in(page, "main", logged_ids) == []
    assert axe_violations(page) == []
    assert page.console_errors == []


def test_findings_name_what_each_finding_is_about(
    demo_stack: UiStack, open_at: Any, logged_ids: re.Pattern[str]
) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/findings")
    rows = page.locator("#findings-list tr.finding")
    assert rows.count() == 10  # nine replies without the dialogue model, one strong negative emotion
    assert ids_in(page, "main", logged_ids) == []
    for row in rows.all():
        focus = row.get_attribute("data-focus")
        link = row.locator("a.explain-link")
        assert link.get_attribute("href") == "/explain?" + str(httpx.QueryParams({"iri": focus}))
        assert link.get_attribute("title") == focus  # the IRI on hover
    about = page.locator("#findings-list a.explain-link .visually-hidden").all_inner_texts()
    assert "finding: Strong negative emotion read on a human about anger 0.88" in about
    # Replies saying the same words are told apart by the robots that said them.
    replies = {text.split(" about ")[1] for text in about if "Reply without" in text}
    assert replies == {f"I am here with you. Tell me more. ({robot})" for robot in ("ARI", "Emotion Mirror", "TIAGo")}
    assert axe_violations(page) == []
    assert page.console_errors == []
