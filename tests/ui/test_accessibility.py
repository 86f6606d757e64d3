"""axe-core in Chromium on every page, and the keyboard paths: the skip link, the graph drawing as a widget
(arrows, Enter, zoom), the list of drawn nodes, focus on the details heading after a link."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.conftest import UiStack
from tests.ui.conftest import axe_violations, demo_pages, screenshot, visit

pytestmark = pytest.mark.browser


def test_no_page_has_a_serious_or_critical_axe_violation(demo_stack: UiStack, open_at: Any) -> None:
    found: dict[str, list[str]] = {}
    for viewport in ("desktop", "phone"):
        page = open_at(viewport)
        for path, name in demo_pages(demo_stack).items():
            visit(page, demo_stack.ui_url + path)
            problems = axe_violations(page)
            if problems:
                found[f"{viewport} {path}"] = problems
                screenshot(page, f"axe-{viewport}-{name}")
    assert found == {}


def test_pages_after_a_form_are_accessible_too(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/logs/insert")
    page.fill("#insert-text", "<https://example.org/a> <https://example.org/b> .\n")  # no object: a syntax error
    page.click("#insert-validate")
    page.wait_for_load_state()
    assert page.locator("#validation-issues tbody tr").count() == 1
    assert axe_violations(page) == []

    page.goto(f"{demo_stack.ui_url}/logs/delete")
    page.fill("#clear-confirm", "not yet")
    page.evaluate("document.getElementById('clear-form').noValidate = true")  # let the server say it
    page.click("#clear-submit")
    page.wait_for_load_state()
    assert "Type DELETE" in page.locator(".banner-error").inner_text()
    assert axe_violations(page) == []


def test_the_axe_check_does_find_a_violation(demo_stack: UiStack, open_at: Any) -> None:
    """The check above can fail: an image without a text alternative is reported as critical."""
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/health")
    page.evaluate(
        "document.querySelector('main').appendChild(document.createElement('img')).src = '/static/favicon.svg'"
    )
    assert any("image-alt" in problem for problem in axe_violations(page))


def test_the_skip_link_leads_to_the_content(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports")
    page.keyboard.press("Tab")
    skip = page.locator("a.skip-link")
    assert page.evaluate("document.activeElement.className") == "skip-link"
    assert skip.is_visible() and skip.inner_text() == "Skip to the content"
    page.keyboard.press("Enter")
    assert page.evaluate("document.activeElement.id") == "content"


def test_single_report_pages_have_a_heading_and_named_explain_links(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports/emotion-timeline")
    assert page.locator("h1").inner_text() == "Emotion timeline"
    headers = page.locator("#report-emotion-timeline thead th").all_inner_texts()
    assert all(header.strip() for header in headers) and headers[-1] == "Explain"
    names = page.locator("a.explain-link").evaluate_all("links => links.map(a => a.textContent)")
    assert names and all(name.startswith("why? ") for name in names)
    assert len(set(names)) == len(names)  # each names what it explains
    assert any(name.startswith("why? happiness on Maria") for name in names)


def test_the_graph_drawing_is_used_with_the_keyboard(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    graph = page.locator("#graph")
    assert graph.get_attribute("role") == "application" and graph.get_attribute("tabindex") == "0"
    graph.focus()
    announced = page.locator("#graph-announce")
    assert announced.inner_text().startswith("ARI (robot)")  # focus starts on a robot
    page.keyboard.press("ArrowDown")  # robots stand in a column where their lane begins
    assert announced.inner_text().startswith("Emotion Mirror (robot)")
    page.keyboard.press("ArrowDown")
    page.keyboard.press("ArrowDown")
    assert "(human" in announced.inner_text()
    human = announced.inner_text().split(" (human")[0]
    page.keyboard.press("Enter")
    page.wait_for_selector("#graph-panel[data-iri]")
    assert page.locator("#graph-panel h2").inner_text() == human

    zoom = page.evaluate("() => document.getElementById('graph-announce').textContent")
    page.keyboard.press("+")
    assert announced.inner_text().startswith("Zoom ") and announced.inner_text() != zoom
    page.keyboard.press("0")
    assert announced.inner_text().startswith("The whole drawing")

    # Following a link in the details moves focus to the new details' heading.
    opened = page.locator("#graph-panel").get_attribute("data-iri")
    link = page.locator("#graph-panel table a").first
    target = link.get_attribute("title")
    link.click()
    page.wait_for_selector(f'#graph-panel[data-iri="{target}"]')
    assert target != opened
    assert page.evaluate("document.activeElement.tagName") == "H2"
    assert page.evaluate("document.activeElement.closest('#graph-panel') !== null")
    assert page.console_errors == []


def test_the_drawn_nodes_are_listed_for_keyboards_and_screen_readers(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    visit(page, f"{demo_stack.ui_url}/kg-graph")
    page.click("#graph-list summary")
    robots = page.locator("#graph-list h3", has_text="Robots")
    assert robots.inner_text() == "Robots (3)"
    drawn = int(page.locator("#graph-stats").get_attribute("data-nodes")) - int(
        page.locator("#graph-stats").get_attribute("data-folded")
    )
    assert page.locator("#graph-list button[data-id]").count() == drawn
    page.locator("#graph-list").get_by_role("button", name="TIAGo", exact=True).click()
    page.wait_for_selector("#graph-panel[data-iri$='robot_tiago']")
    assert page.evaluate("document.activeElement.textContent") == "TIAGo"


def test_an_unreadable_api_answer_is_not_an_axe_problem_either(demo_stack: UiStack) -> None:
    """The error page of a refused token is plain HTML with a heading and a way out."""
    answer = httpx.get(f"{demo_stack.ui_url}/reports/no-such-report", timeout=30)
    assert answer.status_code == 404 and "<h1>" in answer.text
