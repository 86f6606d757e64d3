"""Pages show names, not ids, and the graph reads at first sight: on the demo (robots ARI and TIAGo, humans
Maria and Carlos) and the example robot's log, in real headless Chromium."""

from __future__ import annotations

import re
from typing import Any

import httpx
import pytest

from segb_server.ui.namesakes import Name
from segb_server.ui.participant_names import robots_met
from segb_server.ui.routes.graph import with_readable_labels
from segb_server.ui.routes.shared_context import event_words, summary
from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, visit

pytestmark = pytest.mark.browser

# What an id looks like on screen: a 32-hex digest, or the local name of a robot's or a human's IRI.
ID_TEXT = re.compile(r"[0-9a-f]{32}|\b(?:human|robot)_\w+", re.IGNORECASE)
SPARQL_ACTIVITIES = (
    "PREFIX segb: <http://www.gsi.upm.es/ontologies/segb/ns#>\n"
    "SELECT ?activity ?robot WHERE { ?activity segb:wasPerformedBy ?robot } ORDER BY ?activity"
)


def ids_shown(page: Any, selector: str = "main") -> list[str]:
    return sorted(set(ID_TEXT.findall(page.locator(selector).inner_text())))


def test_the_check_finds_ids() -> None:
    """The pattern the tests below rely on does catch what a newcomer saw."""
    seen = "robot_tiago human_maria human_utterance_c13f6b3122bf3e9c 84272094455f40ce9d773d8aa1e02e06"
    assert len(ID_TEXT.findall(seen)) == 4
    assert ID_TEXT.findall("Maria's utterance (heard by TIAGo) at 10:00:01 — “Hi!”") == []


def test_shared_context_names_robots_people_and_events(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/shared-context")
    assert page.locator(".review").count() >= 1
    assert ids_shown(page) == []
    summaries = page.locator(".context-summary").all_inner_texts()
    said = "“I did not expect to pass on the first try.”"  # as the robot logged it, not lowercased
    # ARI's Maria: told by the robot that heard her, or, when it did not say, by the robots that met her.
    aris = re.compile(rf"Maria's utterance \((heard by ARI|Maria met by ARI, TIAGo)\) at 10:00:11 — {said}")
    assert any(aris.fullmatch(summary) for summary in summaries), summaries
    # TIAGo overheard her without seeing who spoke (the robot is named when its observation says which it is).
    tiagos = re.compile(rf"An unattributed utterance( \(heard by TIAGo\))? at 10:00:11\.500 — {said}")
    assert any(tiagos.fullmatch(summary) for summary in summaries), summaries
    # The example robot's Maria: nobody's observation names a robot, her namesake's qualifier does.
    assert f"Maria's utterance (Maria met by Emotion Mirror) at 10:00:11 — {said}" in summaries
    link = page.locator(".context-summary").first
    assert link.get_attribute("title").startswith("https://") and "/kg-graph?focus=" in link.get_attribute("href")
    assert axe_violations(page) == []
    assert page.console_errors == []


def test_explain_shows_names_for_every_kind_of_seed(demo_stack: UiStack, open_at: Any) -> None:
    rows = httpx.get(f"{demo_stack.api_url}/reports/conversations", params={"limit": 200}, timeout=30).json()["rows"]
    states = httpx.get(f"{demo_stack.api_url}/graph", params={"types": "state", "limit": 50}, timeout=30).json()
    seeds = {row["message"] for row in rows[:: max(1, len(rows) // 6)]} | {states["nodes"][0]["id"]}
    page = open_at("desktop")
    for seed in sorted(seeds):
        visit(page, f"{demo_stack.ui_url}/explain?" + str(httpx.QueryParams({"iri": seed})))
        assert page.locator(".story-step").count() >= 1, seed
        assert ids_shown(page) == [], seed
    assert axe_violations(page) == []


@pytest.mark.parametrize(
    ("kind", "label", "heading"),
    [
        (
            "shared-event",
            "I wish my grandmother could have seen it.",
            r"Shared event about Maria \((ARI, TIAGo|Emotion Mirror)\) at 10:00:21"
            r" — “I wish my grandmother could have seen it.”",
        ),
        ("human", "Maria (ARI, TIAGo)", r"Maria \(ARI, TIAGo\)"),
        ("model", "Emotion Big6 CNN (ARI)", r"Emotion Big6 CNN \(ARI\)"),
        ("state", "TIAGo's state at 10:01:03.500", r"TIAGo's state at 10:01:03.500"),
    ],
)
def test_graph_node_details_show_names(demo_stack: UiStack, open_at: Any, kind: str, label: str, heading: str) -> None:
    drawn = httpx.get(f"{demo_stack.ui_url}/kg-graph/data", timeout=30).json()["nodes"]
    iri = next(node["id"] for node in drawn if node["kind"] == kind and node["label"] == label)
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    page.check("#graph-show-other")  # property values and observations too: rows link to unnamed nodes
    page.fill("#graph-search-input", iri)  # by IRI: found, and never shown
    page.click("#graph-search button")
    page.wait_for_selector(f'#graph-panel[data-iri="{iri}"] h2')
    assert re.fullmatch(heading, page.locator("#graph-panel h2").inner_text())
    assert ids_shown(page, "#graph-panel") == []
    assert page.locator("#graph-panel .panel-iri").get_attribute("title") == iri
    assert axe_violations(page) == []
    assert page.console_errors == []


def test_query_results_say_whose_each_iri_is(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/query?" + str(httpx.QueryParams({"query": SPARQL_ACTIVITIES})))
    links = page.locator("#query-results a.iri")
    assert links.count() >= 10
    shown = links.all_inner_texts()
    titles = [links.nth(i).get_attribute("title") for i in range(links.count())]
    assert shown == titles  # the robots' own namespaces: the whole IRI, the same one the tooltip holds
    assert any("/ari/v1/activity_respond_" in text for text in shown)
    assert any("/tiago/v1/" in text for text in shown)

    prefixed = "SELECT ?kind WHERE { VALUES ?kind { <http://www.w3.org/ns/prov#Activity> } }"
    visit(page, f"{demo_stack.ui_url}/query?" + str(httpx.QueryParams({"query": prefixed})))
    kind = page.locator("#query-results a.iri").first
    assert kind.inner_text() == "prov:Activity" and kind.get_attribute("title") == "http://www.w3.org/ns/prov#Activity"
    assert axe_violations(page) == []


def test_the_model_usage_report_says_what_a_score_measured(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports/ml-usage")
    training = page.locator("#report-ml-usage .evaluation").all_inner_texts()
    assert training and all(re.fullmatch(r"(Accuracy|evaluation score) 0\.71", text) for text in training)
    assert "· score" not in page.locator("#report-ml-usage").inner_text()
    assert axe_violations(page) == []


LANES_AND_NODES = """() => {
  const box = document.getElementById('graph').getBoundingClientRect();
  const cy = document.getElementById('graph')._cyreg.cy;
  const lanes = {};
  cy.nodes().not('.folded').forEach(n => {
    const kind = n.data('kind'), y = n.renderedPosition().y, x = n.renderedPosition().x;
    const lane = lanes[kind] = lanes[kind] || { top: Infinity, bottom: -Infinity, left: Infinity, right: -Infinity };
    lane.top = Math.min(lane.top, y); lane.bottom = Math.max(lane.bottom, y);
    lane.left = Math.min(lane.left, x); lane.right = Math.max(lane.right, x);
  });
  const labels = {};
  document.querySelectorAll('#graph-lanes li').forEach(li => {
    if (li.hidden) { return; }
    const r = li.getBoundingClientRect();
    labels[li.dataset.kind] = { top: r.top - box.top, bottom: r.bottom - box.top };
  });
  return { lanes, labels, width: box.width, height: box.height };
}"""


def assert_lanes_named_where_their_nodes_are(view: dict[str, Any]) -> None:
    """Every lane drawn has its name in view, nearer its own nodes than any other lane's."""
    lanes, labels = view["lanes"], view["labels"]
    assert set(labels) == set(lanes)

    def distance(y: float, lane: dict[str, float]) -> float:
        return max(lane["top"] - y, 0, y - lane["bottom"])

    for kind, label in labels.items():
        assert label["top"] >= 0 and label["bottom"] <= view["height"], kind
        middle = (label["top"] + label["bottom"]) / 2
        nearest = min(lanes, key=lambda other: distance(middle, lanes[other]))
        assert nearest == kind, (kind, label, lanes)
        assert lanes[kind]["top"] >= 0 and lanes[kind]["bottom"] <= view["height"], kind


def test_every_lane_is_in_view_and_named_beside_its_nodes(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    first = page.evaluate(LANES_AND_NODES)
    assert {"robot", "human", "shared-event", "activity", "message", "emotion", "state", "model"} <= set(first["lanes"])
    assert_lanes_named_where_their_nodes_are(first)

    page.click("#graph-fit")
    page.wait_for_timeout(200)
    fitted = page.evaluate(LANES_AND_NODES)
    assert_lanes_named_where_their_nodes_are(fitted)
    # Fit fills the box: the nodes span most of its width and of its height.
    left = min(lane["left"] for lane in fitted["lanes"].values())
    right = max(lane["right"] for lane in fitted["lanes"].values())
    top = min(lane["top"] for lane in fitted["lanes"].values())
    bottom = max(lane["bottom"] for lane in fitted["lanes"].values())
    assert right - left >= 0.8 * fitted["width"] and bottom - top >= 0.75 * fitted["height"], fitted

    page.check("#graph-show-other")  # a lane more, named where it is too
    page.click("#graph-fit")
    page.wait_for_timeout(200)
    assert_lanes_named_where_their_nodes_are(page.evaluate(LANES_AND_NODES))
    assert page.console_errors == []


EDGE_LABELS = """() => {
  const cy = document.getElementById('graph')._cyreg.cy;
  const shown = cy.edges().filter(e => e.pstyle('label').strValue !== '');
  const boxes = shown.map(e => e.boundingBox({ includeNodes: false, includeEdges: false, includeLabels: true }))
    .filter(b => b.w > 0 && b.h > 0);
  const hub = cy.edges('.hub').not('.lit');
  return { shown: shown.length, boxes, lit: cy.edges('.lit').length,
           fadedHub: hub.nonempty() && hub.every(e => e.pstyle('opacity').value < 0.5) };
}"""


def overlapping(boxes: list[dict[str, float]]) -> list[tuple[int, int]]:
    return [
        (i, j)
        for i, a in enumerate(boxes)
        for j, b in enumerate(boxes[i + 1 :], i + 1)
        if a["x1"] < b["x2"] and b["x1"] < a["x2"] and a["y1"] < b["y2"] and b["y1"] < a["y2"]
    ]


def test_edge_labels_never_overlap_and_the_robot_hub_is_faded(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    at_start = page.evaluate(EDGE_LABELS)
    assert at_start["shown"] == 0 and at_start["fadedHub"]  # no label until a node is chosen

    page.locator("#graph").focus()  # focus starts on ARI, whose edges reach most of the drawing
    for _ in range(4):
        page.keyboard.press("+")
    page.wait_for_timeout(300)
    lit = page.evaluate(EDGE_LABELS)
    assert lit["lit"] > 10 and lit["shown"] >= 2
    assert overlapping(lit["boxes"]) == []
    assert len(lit["boxes"]) >= 2  # drawn on screen, measured by cytoscape.js itself

    page.keyboard.press("ArrowDown")  # the next robot: its own edges lit, ARI's faded again
    page.wait_for_timeout(300)
    assert overlapping(page.evaluate(EDGE_LABELS)["boxes"]) == []
    assert page.console_errors == []


def test_unnamed_nodes_are_told_by_robot_kind_and_time_and_namesakes_by_robots() -> None:
    ari, mirror = "https://example.org/ari/v1/", "https://example.org/mirror/v1/"
    graph = {
        "nodes": [
            {"id": ari + "robot_ari", "label": "ARI", "kind": "robot"},
            {"id": mirror + "robot_mirror", "label": "Emotion Mirror", "kind": "robot"},
            {"id": ari + "human_maria", "label": "Maria", "kind": "human"},
            {"id": mirror + "human_maria", "label": "Maria", "kind": "human"},
            {"id": ari + "state_state_2", "label": "state_state_2", "kind": "state", "time": "2026-03-10T10:00:03.5Z"},
            {"id": ari + "model_llm", "label": "llama3.2", "kind": "model"},
            {"id": mirror + "model_llm", "label": "llama3.2", "kind": "model"},
            {"id": ari + "implementation_84272094455f40ce9d773d8aa1e02e06", "label": "", "kind": "other"},
        ],
        "edges": [
            {"id": "e", "source": ari + "state_state_2", "target": ari + "robot_ari", "label": "wasAttributedTo"}
        ],
    }
    met = robots_met(
        [
            {"human": ari + "human_maria", "robotName": "TIAGo", "interactions": 1},
            {"human": ari + "human_maria", "robotName": "ARI", "interactions": 12},
            {"human": mirror + "human_maria", "robotName": "Emotion Mirror", "interactions": 12},
        ]
    )
    labels = [node["label"] for node in with_readable_labels(graph, met)["nodes"]]
    assert labels == [
        "ARI",
        "Emotion Mirror",
        "Maria (ARI, TIAGo)",  # the robot that met her most first
        "Maria (Emotion Mirror)",
        "ARI's state at 10:00:03.500",
        "llama3.2 (ARI)",  # no activity used it: the robot whose namespace it is in
        "llama3.2 (Emotion Mirror)",
        "implementation",
    ]


def test_a_shared_event_is_told_by_kind_subject_robot_time_and_words() -> None:
    assert event_words("human_utterance") == "utterance" and event_words("door-opening") == "door opening"
    maria = "https://example.org/ari/v1/human_maria"
    context = {
        "event_kind": "human_utterance",
        "subject_uri": maria,
        "modality": "speech",
        "observed_at": "2026-03-10T10:00:01Z",
        "canonical_text": "hi! i passed my driving test today!",
        "observations": [{"robot_uri": "https://example.org/tiago/v1/robot_tiago", "text": "Hi! I passed!"}],
    }
    names = {maria: Name("Maria"), "https://example.org/tiago/v1/robot_tiago": Name("TIAGo")}
    assert summary(context, names) == "Maria's utterance (heard by TIAGo) at 10:00:01 — “Hi! I passed!”"
    unknown = {**context, "subject_uri": None, "modality": "vision", "observations": [{}]}
    assert summary(unknown, names) == "An unattributed utterance at 10:00:01 — “hi! i passed my driving test today!”"
