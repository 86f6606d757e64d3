"""The knowledge graph reads at first sight, on the demo and the example robot's log, in headless Chromium on a
desktop, a phone, a wide and a high-density screen: every lane in view and named on a band that holds its nodes (at
the start, after Fit, zoomed in), the robots' many edges faint and unlabelled, labels only where they fit, and Fit
filling the box."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, new_page, visit

pytestmark = pytest.mark.browser

SIZES = {"desktop": (1440, 900), "phone": (390, 844), "wide": (2560, 1300), "retina": (1440, 900)}
PIXEL_RATIOS = {"retina": 2}  # cytoscape.js decides which labels are big enough to draw in device pixels
LANES = ("robot", "human", "shared-event", "activity", "message", "emotion", "state", "model")

# Each drawn node's box and each lane's band (its list item) and name (the text in it), in pixels from the
# drawing's top left corner, as cytoscape.js and the DOM give them.
VIEW = """() => {
  const graph = document.getElementById('graph');
  const cy = graph._cyreg.cy;
  const rect = graph.getBoundingClientRect();
  const left = rect.left + graph.clientLeft, top = rect.top + graph.clientTop;  // where cytoscape.js counts from
  const relative = r => ({ x1: r.left - left, x2: r.right - left, y1: r.top - top, y2: r.bottom - top });
  const plain = b => ({ x1: b.x1, x2: b.x2, y1: b.y1, y2: b.y2 });
  const bare = { includeLabels: false, includeOverlays: false, includeUnderlays: false };
  const drawn = cy.nodes().not('.folded');
  const nodes = {};
  drawn.forEach(n => (nodes[n.data('kind')] = nodes[n.data('kind')] || []).push(plain(n.renderedBoundingBox(bare))));
  // cytoscape.js draws a label when its size at the zoom rounded up to a power of two reaches min-zoomed-font-size.
  const scale = Math.pow(2, Math.ceil(Math.log2(cy.zoom() * window.devicePixelRatio)));
  const labelled = drawn.filter(n => n.pstyle('label').strValue !== '' &&
    n.pstyle('font-size').pfValue * scale >= n.pstyle('min-zoomed-font-size').pfValue);
  const nodesOnly = plain(drawn.renderedBoundingBox(bare));
  const withLabels = labelled.nonempty()
    ? plain(labelled.renderedBoundingBox({ includeOverlays: false, includeUnderlays: false })) : nodesOnly;
  const bands = {}, names = {};
  document.querySelectorAll('#graph-lanes li').forEach(li => {
    if (li.hidden || getComputedStyle(li).display === 'none') { return; }
    bands[li.dataset.kind] = relative(li.getBoundingClientRect());
    const text = document.createRange();
    text.selectNodeContents(li);
    names[li.dataset.kind] = relative(text.getBoundingClientRect());
  });
  return { nodes, bands, names, width: graph.clientWidth, height: graph.clientHeight, zoom: cy.zoom(), nodesOnly,
           drawing: { x1: Math.min(nodesOnly.x1, withLabels.x1), x2: Math.max(nodesOnly.x2, withLabels.x2),
                      y1: Math.min(nodesOnly.y1, withLabels.y1), y2: Math.max(nodesOnly.y2, withLabels.y2) } };
}"""

# The labels drawn now and in view, nodes' and edges', as cytoscape.js measures them (model units), and the hub's
# edges as drawn.
LABELS = """() => {
  const cy = document.getElementById('graph')._cyreg.cy;
  const ext = cy.extent();
  const drawn = elements => elements.filter(e => e.visible() && e.pstyle('label').strValue !== '').filter(e => {
    const b = e.boundingBox({ includeNodes: false, includeEdges: false, includeLabels: true });
    return b.w > 0 && b.h > 0 && b.x1 < ext.x2 && b.x2 > ext.x1 && b.y1 < ext.y2 && b.y2 > ext.y1;
  });
  const boxes = elements => drawn(elements).map(e => {
    const b = e.boundingBox({ includeNodes: false, includeEdges: false, includeLabels: true });
    return { x1: b.x1, x2: b.x2, y1: b.y1, y2: b.y2 };
  });
  const hub = cy.edges('.hub').not('.lit');
  const other = cy.edges().not('.hub');
  return {
    edges: boxes(cy.edges()), nodes: boxes(cy.nodes()), zoom: cy.zoom(),
    kinds: [...new Set(drawn(cy.nodes()).map(n => n.data('kind')))],
    hubEdges: hub.length,
    hubLabelled: hub.filter(e => e.pstyle('label').strValue !== '').length,
    hubOpacity: Math.max(...hub.map(e => e.pstyle('opacity').value)),
    hubBelow: hub.every(e => e.pstyle('z-index').value < other[0].pstyle('z-index').value),
  };
}"""

ZOOM_AT_MIDDLE = """(level) => {
  const cy = document.getElementById('graph')._cyreg.cy;
  cy.zoom({ level, renderedPosition: { x: cy.width() * 0.6, y: cy.height() / 2 } });
}"""


@pytest.fixture(scope="module")
def sized(browser: Any) -> Iterator[Any]:
    """`sized("wide")` → a fresh page of that viewport (closed at the end of the module)."""
    contexts: list[Any] = []

    def opener(size: str) -> Any:
        return new_page(browser, contexts, SIZES[size], PIXEL_RATIOS.get(size, 1))

    yield opener
    for context in contexts:
        context.close()


def inside(inner: dict[str, float], outer: dict[str, float], slack: float = 0.5) -> bool:
    return (
        inner["x1"] >= outer["x1"] - slack
        and inner["x2"] <= outer["x2"] + slack
        and inner["y1"] >= outer["y1"] - slack
        and inner["y2"] <= outer["y2"] + slack
    )


def crossing(a: dict[str, float], b: dict[str, float]) -> bool:
    return a["x1"] < b["x2"] and b["x1"] < a["x2"] and a["y1"] < b["y2"] and b["y1"] < a["y2"]


def overlapping(boxes: list[dict[str, float]]) -> list[tuple[int, int]]:
    return [(i, j) for i, a in enumerate(boxes) for j, b in enumerate(boxes[i + 1 :], i + 1) if crossing(a, b)]


def assert_lanes_named_on_their_bands(view: dict[str, Any], all_in_view: bool) -> None:
    """Each lane's band holds every node of its lane and no other lane's; its name is in view, on its band,
    and covers no node. With `all_in_view`, every lane has nodes in view too."""
    box = {"x1": 0, "x2": view["width"], "y1": 0, "y2": view["height"]}
    in_view = {kind for kind, nodes in view["nodes"].items() if any(crossing(node, box) for node in nodes)}
    if all_in_view:
        assert in_view == set(view["nodes"]), sorted(set(view["nodes"]) - in_view)
    assert set(view["names"]) == in_view, (sorted(view["names"]), sorted(in_view))
    for kind, band in view["bands"].items():
        for node in view["nodes"][kind]:
            assert band["y1"] <= node["y1"] and node["y2"] <= band["y2"], (kind, band, node)
        for other, nodes in view["nodes"].items():
            if other != kind:
                assert not any(band["y1"] < n["y1"] < band["y2"] for n in nodes), (kind, other, band)
        name = view["names"][kind]
        assert inside(name, box) and band["y1"] <= name["y1"] and name["y2"] <= band["y2"], (kind, name, band)
        covered = [node for nodes in view["nodes"].values() for node in nodes if crossing(name, node)]
        assert covered == [], (kind, name, covered)


@pytest.mark.parametrize("size", ["desktop", "phone", "wide"])
def test_the_first_view_shows_every_lane_named_beside_its_nodes(demo_stack: UiStack, sized: Any, size: str) -> None:
    page = sized(size)
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    view = page.evaluate(VIEW)
    assert set(LANES) <= set(view["nodes"])
    assert_lanes_named_on_their_bands(view, all_in_view=True)
    assert axe_violations(page) == []
    assert page.console_errors == []


@pytest.mark.parametrize("size", ["desktop", "phone", "wide"])
def test_fit_fills_the_box_and_keeps_every_lane_named(demo_stack: UiStack, sized: Any, size: str) -> None:
    page = sized(size)
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    page.click("#graph-fit")
    page.wait_for_timeout(200)
    view = page.evaluate(VIEW)
    box = {"x1": 0, "x2": view["width"], "y1": 0, "y2": view["height"]}
    assert inside(view["drawing"], box), view["drawing"]  # nothing cut off, the labels drawn included
    drawing = view["nodesOnly"]
    wide = (drawing["x2"] - drawing["x1"]) / view["width"]
    tall = (drawing["y2"] - drawing["y1"]) / view["height"]
    assert wide >= 0.7 and tall >= 0.7, (wide, tall)
    assert_lanes_named_on_their_bands(view, all_in_view=True)

    page.locator("#graph").focus()
    for _ in range(3):
        page.keyboard.press("+")  # zooms around the node focused: the first robot
    page.wait_for_timeout(200)
    assert_lanes_named_on_their_bands(page.evaluate(VIEW), all_in_view=False)

    page.check("#graph-show-other")  # a lane more: Fit makes room for it, named on its band too
    page.click("#graph-fit")
    page.wait_for_timeout(200)
    view = page.evaluate(VIEW)
    assert "other" in view["names"]
    assert_lanes_named_on_their_bands(view, all_in_view=True)
    assert page.console_errors == []


@pytest.mark.parametrize("size", ["desktop", "phone", "retina"])
def test_labels_are_shown_only_where_they_fit(demo_stack: UiStack, sized: Any, size: str) -> None:
    """No two labels drawn overlap, at the first view and zoomed in; zooming in shows more of them."""
    page = sized(size)
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    first = page.evaluate(LABELS)
    assert first["edges"] == []  # too small to read there
    assert overlapping(first["nodes"]) == [] and len(first["nodes"]) >= 6  # robots, humans, messages
    assert first["hubEdges"] >= 30 and first["hubLabelled"] == 0  # the robots' wasPerformedBy among them
    assert first["hubOpacity"] <= 0.15 and first["hubBelow"], first

    most, kinds = 0, set(first["kinds"])
    for level in (0.85, 1, 1.3, 1.8, 2.5, 3.5):  # zoomed in step by step past the sizes where labels are drawn
        page.evaluate(ZOOM_AT_MIDDLE, level)
        page.wait_for_timeout(200)
        zoomed = page.evaluate(LABELS)
        assert overlapping(zoomed["edges"] + zoomed["nodes"]) == [], zoomed["zoom"]
        assert zoomed["hubLabelled"] == 0
        most, kinds = max(most, len(zoomed["edges"])), kinds | set(zoomed["kinds"])
    assert most >= 3  # edges between activities, messages and emotions say what they are once they fit
    assert {"activity", "emotion"} <= kinds - set(first["kinds"])  # and activities, emotions… their names

    page.locator("#graph").focus()  # focus starts on a robot: its edges are lit, their labels where they fit
    page.wait_for_timeout(250)
    lit = page.evaluate(LABELS)
    assert overlapping(lit["edges"] + lit["nodes"]) == []
    assert axe_violations(page) == []
    assert page.console_errors == []
