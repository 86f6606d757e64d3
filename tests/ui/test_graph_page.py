"""/kg-graph and /explain in real headless Chromium, on data published with the real client."""

from __future__ import annotations

import time
from typing import Any

import httpx
import pytest

from tests.conftest import ARTIFACTS, UiStack
from tests.support.robot_posts import ntriples_of, replicate
from tests.support.scenarios import keep_busy, lobby
from tests.support.settle import settle

pytestmark = pytest.mark.browser


def open_graph(page, url: str, timeout_ms: int = 60_000) -> dict:  # type: ignore[no-untyped-def]
    started = time.perf_counter()
    page.goto(url)
    page.wait_for_selector("#graph[data-ready=true]", timeout=timeout_ms)
    figures = page.evaluate("window.segbGraph")
    figures["wall_ms"] = round((time.perf_counter() - started) * 1000)
    return figures


def test_graph_page_draws_searches_and_opens_node_details(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)
    figures = open_graph(page, f"{ui_stack.ui_url}/kg-graph")
    api_graph = httpx.get(f"{ui_stack.api_url}/graph").json()
    assert figures["nodes"] == len(api_graph["nodes"]) and figures["edges"] == len(api_graph["edges"])
    assert page.locator("#graph-stats").get_attribute("data-truncated") == "false"

    page.fill("#graph-search-input", "Juan")
    page.click("#graph-search button")
    page.wait_for_selector("#graph-panel[data-iri]")
    assert page.locator("#graph-panel").get_attribute("data-iri") == str(scenario.iris["juan"])
    panel = page.locator("#graph-panel").inner_text()
    assert "Juan" in panel and "foaf:firstName" in panel and "schema:sender" in panel

    page.click("#graph-panel a.button:has-text('Explain')")
    page.wait_for_load_state()
    assert "/explain?iri=" in page.url
    assert page.console_errors == []


def test_node_details_say_when_more_statements_point_at_the_node(ui_stack: UiStack, page: Any) -> None:
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)
    tiago = str(scenario.iris["tiago"])
    keep_busy(ui_stack.api_url, tiago, 600)
    open_graph(page, f"{ui_stack.ui_url}/kg-graph?" + str(httpx.QueryParams({"focus": tiago, "depth": "0"})))
    page.fill("#graph-search-input", "TIAGo")
    page.click("#graph-search button")
    page.wait_for_selector("#graph-panel[data-iri]")
    note = page.locator("#graph-panel .incoming-truncated")
    assert "Only the first 500 incoming statements are listed" in note.inner_text()
    assert page.console_errors == []


def test_graph_page_filters_by_robot(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)
    tiago = str(scenario.iris["tiago"])
    figures = open_graph(page, f"{ui_stack.ui_url}/kg-graph?" + str(httpx.QueryParams({"robot": tiago})))
    only_tiago = httpx.get(f"{ui_stack.api_url}/graph", params={"robot": tiago}).json()
    assert figures["nodes"] == len(only_tiago["nodes"])
    labels = {node["label"] for node in only_tiago["nodes"]}
    assert "TIAGo" in labels and "Where is the pharmacy?" in labels and "ARI" not in labels
    assert page.console_errors == []


def test_graph_page_expands_a_neighbourhood_and_finds_nodes_not_drawn_yet(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)
    focus = httpx.QueryParams({"focus": str(scenario.iris["maria"]), "depth": "1"})
    figures = open_graph(page, f"{ui_stack.ui_url}/kg-graph?{focus}")

    def drawn() -> int:
        return int(page.locator("#graph-stats").get_attribute("data-nodes"))

    def wait_for_more_than(count: int) -> None:
        deadline = time.monotonic() + 15
        while drawn() <= count:
            assert time.monotonic() < deadline, "no nodes were added"
            page.wait_for_timeout(100)

    page.fill("#graph-search-input", "message_maria_1")
    page.click("#graph-search button")
    page.wait_for_selector(f"#graph-panel[data-iri='{scenario.iris['maria_1']}']")
    page.click("#graph-panel button:has-text('Expand neighbours')")
    wait_for_more_than(figures["nodes"])  # the listening activity and ARI's answer join the drawing
    expanded = drawn()

    page.fill("#graph-search-input", "Second floor")  # not drawn: found on the server, merged, focused
    page.click("#graph-search button")
    page.wait_for_selector(f"#graph-panel[data-iri='{scenario.iris['tiago_1']}']")
    assert drawn() > expanded
    assert page.console_errors == []


def test_explain_page_tells_the_emotion_mirror_exchange_in_order(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/explain?" + str(httpx.QueryParams({"iri": str(scenario.iris["ari_1"])})))
    sentences = page.locator(".story-sentence").all_inner_texts()
    assert sentences == [
        "Maria said “I passed my driving test today!” (heard by ARI via speech)",
        "ARI analysed emotion with Emotion Big6 CNN 1.0: happiness 0.9 on Maria",
        "ARI said “Congratulations, Maria!”",
        "Maria said “Thanks!” (heard by ARI)",
    ]
    roles = [page.locator(".story-step").nth(i).get_attribute("class").split("role-")[1] for i in range(4)]
    assert roles == ["cause", "cause", "seed", "effect"]
    assert page.console_errors == []


def test_explain_links_from_reports_lead_to_the_story(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    lobby().publish_all(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/reports")
    page.locator("#report-emotion-timeline tr", has_text="Juan").locator("a.explain-link").click()
    page.wait_for_load_state()
    assert (
        page.locator(".story-step.role-seed .story-sentence").inner_text()
        == "TIAGo analysed emotion: anger 0.8 on Juan"
    )
    assert page.console_errors == []


def test_explain_tells_a_robots_own_emotion_as_expressed(ui_stack: UiStack, page: Any) -> None:
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/explain?" + str(httpx.QueryParams({"iri": str(scenario.iris["express_ari_1"])})))
    assert page.locator(".story-step.role-seed .story-sentence").inner_text() == "ARI expressed happiness 0.6"
    assert page.console_errors == []


@pytest.mark.parametrize("interactions", [25, 125])
def test_graph_page_stays_interactive_with_thousands_of_nodes(ui_stack: UiStack, page, interactions: int) -> None:  # type: ignore[no-untyped-def]
    """Two robots' logs made by the real client (about 1,000 and 5,000 nodes); time to first interactive render
    is recorded in test-artifacts/graph-timings.txt."""
    for copy in replicate(ntriples_of(interactions, "mirror"), 2):
        response = httpx.post(
            f"{ui_stack.api_url}/ttl", content=copy, headers={"Content-Type": "application/n-triples"}, timeout=120
        )
        assert response.status_code == 201
    settle(ui_stack.api_url)  # the graph is drawn from its index, current once the posts are applied
    figures = open_graph(page, f"{ui_stack.ui_url}/kg-graph?limit=20000", timeout_ms=120_000)
    assert figures["nodes"] >= (1000 if interactions < 100 else 5000)
    # Interactive: a search focuses a node deep in the drawing and its panel opens.
    page.fill("#graph-search-input", "Utterance 7:")
    page.click("#graph-search button")
    page.wait_for_selector("#graph-panel[data-iri]", timeout=30_000)
    assert "Utterance 7:" in page.locator("#graph-panel h2").inner_text()
    ARTIFACTS.mkdir(exist_ok=True)
    with (ARTIFACTS / "graph-timings.txt").open("a") as log:
        log.write(f"{figures}\n")
    assert page.console_errors == []


def test_graph_reads_at_first_sight(demo_stack_graph: tuple[UiStack, dict], page: Any) -> None:
    """Named lanes; robots, humans and messages labelled at the starting zoom, the other kinds not; "other"
    nodes folded behind a toggle."""
    stack, api_graph = demo_stack_graph
    open_graph(page, f"{stack.ui_url}/kg-graph")
    lanes = [lane for lane in page.locator("#graph-lanes li").all() if lane.is_visible()]
    assert [lane.inner_text() for lane in lanes][:3] == ["ROBOTS", "HUMANS", "SHARED EVENTS"]  # upper-cased by CSS

    shown = page.evaluate("window.segbGraph.labelsShown()")
    kinds = {label.split(": ", 1)[0] for label in shown}
    assert {"robot", "human", "message"} <= kinds
    assert kinds <= {"robot", "human", "message"}  # activities, emotions… wait for hover, focus or zoom
    assert "robot: ARI" in shown and "human: Maria (ARI, TIAGo)" in shown

    others = sum(1 for node in api_graph["nodes"] if node["kind"] == "other")
    stats = page.locator("#graph-stats")
    assert others > 50 and stats.get_attribute("data-folded") == str(others)
    assert f"{others} other nodes folded" in stats.inner_text()
    page.check("#graph-show-other")
    assert stats.get_attribute("data-folded") == "0"
    assert page.locator("#graph-lanes li.lane-other").count() == 1
    page.click("#graph-fit")
    page.wait_for_timeout(200)
    assert page.locator("#graph-lanes li.lane-other").is_visible()
    assert page.console_errors == []


def test_node_details_tell_vocabularies_apart_and_keep_the_iri_inside(
    demo_stack_graph: tuple[UiStack, dict], page: Any
) -> None:
    stack, _ = demo_stack_graph
    open_graph(page, f"{stack.ui_url}/kg-graph")
    page.fill("#graph-search-input", "Carlos")
    page.click("#graph-search button")
    page.wait_for_selector("#graph-panel[data-iri$='human_carlos']")
    persons = page.locator("#graph-panel tr", has_text="rdf:type").filter(has_text="Person")
    assert sorted(row.locator(".vocabulary").inner_text().strip() for row in persons.all()) == [
        "foaf:Person",
        "prov:Person",
    ]
    iri = page.locator("#graph-panel .panel-iri")
    assert iri.get_attribute("title").endswith("/human_carlos") and iri.inner_text() == "Copy IRI"
    assert iri.evaluate("p => p.scrollWidth <= p.clientWidth")
    box, panel = iri.bounding_box(), page.locator("#graph-panel").bounding_box()
    assert box["x"] + box["width"] <= panel["x"] + panel["width"]


@pytest.fixture(scope="module")
def demo_stack_graph(demo_stack: UiStack) -> tuple[UiStack, dict]:
    return demo_stack, httpx.get(f"{demo_stack.api_url}/graph", params={"limit": 1500}, timeout=30).json()
