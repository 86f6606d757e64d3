"""Fixtures of the UI tests: a stack holding what a newcomer sees (the demo dataset, then the example robot),
pages at given viewport sizes, and axe-core run inside Chromium."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from segb_server.backend.demo import publish_demo
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.examples.emotion_mirror import run
from tests.conftest import ARTIFACTS, UiStack, start_ui_stack
from tests.support.net import free_port
from tests.support.settle import settle

AXE = Path(__file__).resolve().parents[1] / "support" / "axe" / "axe.min.js"
REPORTS = ["participants", "conversations", "emotion-timeline", "extreme-emotions", "ml-usage", "robot-states"]
VIEWPORTS = {"desktop": (1440, 900), "phone": (390, 844)}


def run_example_robot(api_url: str) -> None:
    """The example robot's default script, replies from the fallback (no Ollama answers on a closed port)."""
    assert run.main(["--server", api_url, "--ollama-host", f"http://127.0.0.1:{free_port()}"]) == 0


@pytest.fixture(scope="module")
def demo_stack() -> Iterator[UiStack]:
    """`segb demo` published to a fresh server, then the example robot run against it: two robots' Marias,
    one model name registered by three robots, shared contexts with a case to review."""
    store = OxigraphStore("http://amor-segb/events")
    stacks = start_ui_stack(store)
    stack = next(stacks)
    try:
        assert "demo dataset published" in publish_demo(stack.api_url)
        run_example_robot(stack.api_url)
        settle(stack.api_url)  # reports and graph are read from views kept current from the journal
        yield stack
    finally:
        stacks.close()
        store.close()


def demo_pages(stack: UiStack) -> dict[str, str]:
    """Every page of the UI with content in it (path → a name for messages and screenshots)."""
    answer = httpx.get(f"{stack.api_url}/reports/conversations", params={"limit": 1}, timeout=30).json()
    message, robot = answer["rows"][0]["message"], answer["rows"][0]["robot"]
    pages = {
        "/reports": "reports",
        "/findings": "findings",
        **{f"/reports/{name}": f"report-{name}" for name in REPORTS},
        "/timeline?" + str(httpx.QueryParams({"robot": robot})): "timeline",
        "/timeline": "timeline-empty",
        "/kg-graph": "graph",
        "/explain?" + str(httpx.QueryParams({"iri": message})): "explain",
        "/explain": "explain-empty",
        "/query?example=reports/participants": "query",
        "/query?" + str(httpx.QueryParams({"query": "SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }"})): "query-answer",
        "/ledger": "ledger",
        "/shared-context": "shared-context",
        "/logs": "logs",
        "/logs/insert": "insert",
        "/logs/delete": "clear",
        "/health": "health",
        "/session": "session",
        "/no-such-page": "not-found",
    }
    return pages


@pytest.fixture(scope="module")
def open_at(browser: Any) -> Iterator[Callable[[str], Any]]:
    """`open_at("phone")` → a fresh page of that viewport size (closed at the end of the module)."""
    contexts: list[Any] = []

    def opener(viewport: str) -> Any:
        return new_page(browser, contexts, VIEWPORTS[viewport])

    yield opener
    for context in contexts:
        context.close()


def new_page(browser: Any, contexts: list[Any], size: tuple[int, int], pixel_ratio: float = 1) -> Any:
    """A page in a context of its own (added to `contexts`, to close), its script errors kept in
    `page.console_errors`."""
    width, height = size
    context = browser.new_context(viewport={"width": width, "height": height}, device_scale_factor=pixel_ratio)
    contexts.append(context)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.console_errors = errors
    return page


def words_split(page: Any, selector: str) -> list[str]:
    """The words inside `selector`'s elements that the page breaks across lines (a text hidden but for screen
    readers excepted)."""
    return page.evaluate(SPLIT_WORDS, selector)  # type: ignore[no-any-return]


SPLIT_WORDS = """(selector) => {
  const split = [];
  for (const element of document.querySelectorAll(selector)) {
    const walker = document.createTreeWalker(element, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node; node = walker.nextNode()) {
      if (node.parentElement.closest(".visually-hidden")) continue;
      for (const match of node.data.matchAll(/\\S+/g)) {
        const range = document.createRange();
        range.setStart(node, match.index);
        range.setEnd(node, match.index + match[0].length);
        const lines = new Set([...range.getClientRects()].map(rect => Math.round(rect.top)));
        if (lines.size > 1) split.push(match[0]);
      }
    }
  }
  return split;
}"""


def visit(page: Any, url: str) -> None:
    page.goto(url)
    if "/kg-graph" in url:
        page.wait_for_selector("#graph[data-ready=true]", timeout=60_000)
    if "/timeline?" in url:
        page.wait_for_selector("#timeline-progress:has-text('events in this window')", timeout=60_000)


def axe_violations(page: Any, impacts: tuple[str, ...] = ("serious", "critical")) -> list[str]:
    """axe-core's violations of these impacts on the page as it is now, one line each. The script is evaluated
    through the browser's debugging protocol, so the page's Content-Security-Policy stays in force."""
    if not page.evaluate("typeof window.axe !== 'undefined'"):
        page.evaluate(AXE.read_text(encoding="utf-8"))
    found = page.evaluate(
        """async (impacts) => {
          const result = await axe.run(document, { resultTypes: ["violations"] });
          return result.violations.filter(v => impacts.includes(v.impact)).map(v =>
            `${v.impact} ${v.id}: ${v.help} — ${v.nodes.slice(0, 3).map(n => n.target.join(" ")).join(" | ")}`);
        }""",
        list(impacts),
    )
    return list(found)


def screenshot(page: Any, name: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=True)
