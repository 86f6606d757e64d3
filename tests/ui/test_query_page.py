"""/query in real headless Chromium: the editor starts with every prefix, the example menu loads a report query,
running it shows the published rows with IRIs leading to /explain, errors show where and why, updates are
refused, robot text stays text, and the CSV download holds the answer."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import httpx
import pytest
from pyoxigraph import Literal

from segb_server.backend.vocabulary import PREFIXES
from tests.conftest import UiStack
from tests.support.scenarios import lobby

pytestmark = pytest.mark.browser

HOSTILE = '<script>window.__pwned = 1</script><img src=x onerror="window.__pwned = 2">'
NAMES = (
    "PREFIX foaf: <http://xmlns.com/foaf/0.1/>\n"
    "SELECT ?human ?name WHERE { ?human foaf:firstName ?name } ORDER BY ?name"
)


def run(page, ui_url: str, query: str) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_url}/query")
    page.fill("#query-editor", query)
    page.click("#query-run")
    page.wait_for_load_state()


def test_the_editor_starts_with_every_prefix_and_an_example_report_runs(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    scenario = lobby()
    scenario.publish_all(ui_stack.api_url)

    page.goto(f"{ui_stack.ui_url}/query")
    assert page.locator("nav a[aria-current=page]").inner_text() == "Query"
    editor = page.locator("#query-editor")
    for name, namespace in PREFIXES.items():
        assert f"PREFIX {name}: <{namespace}>" in editor.input_value()

    page.select_option("#example-menu", "reports/participants")
    assert editor.input_value().startswith("# title: Participants")
    assert "?param_robot" in editor.input_value()
    page.click("#query-run")
    page.wait_for_load_state()

    assert "query=" in page.url
    rows = page.locator("#query-results tbody tr")
    assert rows.count() >= 2
    headers = page.locator("#query-results thead th").all_inner_texts()
    assert headers[:2] == ["human", "humanName"]
    maria = str(scenario.iris["maria"])
    link = page.locator(f'#query-results a.iri[title="{maria}"]').first
    assert link.inner_text() == maria  # the whole IRI: its last part alone does not say whose Maria
    graph_link = page.locator(f'#query-results a.graph-link[title="Show {maria} in the graph"]').first
    assert graph_link.get_attribute("href").startswith("/kg-graph?focus=")
    link.click()
    page.wait_for_load_state()
    assert "/explain?iri=" in page.url
    assert page.locator("h1").inner_text() == "Why did it happen?"
    assert page.console_errors == []


def test_the_menu_loads_an_example_without_javascript_too(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_stack.ui_url}/query?example=reports/robot-states")
    assert page.locator("#query-editor").input_value().startswith("# title: ")
    assert page.locator("#example-menu").input_value() == "reports/robot-states"
    assert page.locator("#query-results").count() == 0  # loaded, not run


def test_a_syntax_error_is_shown_with_its_line_and_column(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    broken = "PREFIX foaf: <http://xmlns.com/foaf/0.1/>\nSELECT ?name WHERE {\n  ?h foaf:firstName ?name .\n"
    broken += "  FILTER(?name = )\n}"
    expected = httpx.post(f"{ui_stack.api_url}/query/validate", json={"query": broken}).json()
    assert expected["line"] == 4

    run(page, ui_stack.ui_url, broken)

    assert page.locator("#query-error h2").inner_text() == "The query did not run"
    assert page.locator("#error-position").inner_text() == f"Line {expected['line']}, column {expected['column']}"
    assert "Invalid SPARQL syntax at line 4" in page.locator("#query-error .banner-error").inner_text()
    assert page.locator("#query-editor").input_value() == broken  # kept for fixing


def test_an_update_is_refused_and_changes_nothing(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    run(
        page, ui_stack.ui_url, "INSERT DATA { <https://example.org/a> <https://example.org/b> <https://example.org/c> }"
    )

    assert page.locator("#query-error h2").inner_text() == "Refused: this endpoint is read-only"
    assert "SPARQL Update (INSERT) is not allowed" in page.locator("#query-error").inner_text()
    assert ui_stack.store.count() == 0


def test_robot_text_in_results_stays_text_and_the_csv_download_holds_it(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    turtle = f"<https://example.org/eve> <http://xmlns.com/foaf/0.1/firstName> {Literal(HOSTILE)} ."
    posted = httpx.post(f"{ui_stack.api_url}/ttl", content=turtle, headers={"Content-Type": "text/turtle"})
    assert posted.status_code == 201, posted.text

    run(page, ui_stack.ui_url, NAMES)

    cells = page.locator("#query-results tbody tr td")
    assert cells.nth(1).inner_text() == HOSTILE
    assert page.locator("#query-results img").count() == 0
    assert page.evaluate("window.__pwned") is None
    with page.expect_download() as started:
        page.click("#download-csv")
    download = started.value
    assert download.suggested_filename == "query.csv"
    rows = list(csv.reader(io.StringIO(Path(download.path()).read_text(encoding="utf-8"))))
    assert rows == [["human", "name"], ["https://example.org/eve", HOSTILE]]
    assert page.console_errors == []


def test_the_example_menu_keeps_its_choice_after_a_run(ui_stack: UiStack, page: Any) -> None:
    lobby().publish_all(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/query")
    first = page.locator("#example-menu option").first.get_attribute("value")
    page.select_option("#example-menu", "reports/robot-states")
    page.click("#example-load")  # through the server, as without JavaScript
    page.wait_for_load_state()
    page.click("#query-run")
    page.wait_for_load_state()
    assert page.locator("#query-results tbody tr").count() > 0
    assert page.locator("#example-menu").input_value() == "reports/robot-states" != first

    page.select_option("#example-menu", "reports/participants")  # through the page's script
    page.click("#query-run")
    page.wait_for_load_state()
    assert page.locator("#example-menu").input_value() == "reports/participants"
    assert page.console_errors == []


def test_numbers_and_times_show_as_values_with_their_datatype_on_hover(ui_stack: UiStack, page: Any) -> None:
    lobby().publish_all(ui_stack.api_url)
    run(
        page,
        ui_stack.ui_url,
        "PREFIX prov: <http://www.w3.org/ns/prov#>\n"
        "SELECT ?triples ?first WHERE { { SELECT (COUNT(*) AS ?triples) WHERE { ?s ?p ?o } }\n"
        "  { SELECT (MIN(?t) AS ?first) WHERE { ?activity prov:startedAtTime ?t } } }",
    )
    count, first = page.locator("#query-results tbody td").all()
    assert count.inner_text().isdigit() and "^^" not in count.inner_text()
    assert count.locator(".literal").get_attribute("title") == "xsd:integer"
    assert first.inner_text() == "2026-03-09T09:00:00Z"
    assert first.locator(".literal").get_attribute("title") == "xsd:dateTime"
    assert page.console_errors == []
