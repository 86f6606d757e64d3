"""The operator pages in real headless Chromium: inserting a log (check, what it would add, publish, receipt;
errors with line and column; a file upload), clearing the graph (typed confirmation), the whole graph as a
download, CSRF refusals and the admin role."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from pyoxigraph import RdfFormat, parse

from segb_server.backend.auth import mint_token
from tests.conftest import UiStack, start_ui_stack
from tests.support.scenarios import lobby

pytestmark = pytest.mark.browser

SECRET = "o" * 40
BROKEN = '@prefix ex: <https://example.org/> .\nex:eve a ex:Person ;\n  ex:says "unclosed .\n'
NEW_LOG = (
    "@prefix foaf: <http://xmlns.com/foaf/0.1/> .\n"
    '<https://example.org/people/eve> a foaf:Person ; foaf:firstName "Eve" .\n'
    '<https://example.org/people/zoe> a foaf:Person ; foaf:firstName "Zoe" .\n'
)


def stored(stack: UiStack) -> int:
    return stack.store.count()


def test_a_syntax_error_is_shown_with_its_line_and_column(ui_stack: UiStack, page: Any) -> None:
    expected = httpx.post(f"{ui_stack.api_url}/ttl/validate", json={"ttl_content": BROKEN}, timeout=30).json()
    issue = expected["issues"][0]
    assert issue["line"] and issue["column"]

    page.goto(f"{ui_stack.ui_url}/logs/insert")
    assert page.locator("nav a[aria-current=page]").inner_text() == "Insert a log"
    page.fill("#insert-text", BROKEN)
    page.click("#insert-validate")
    page.wait_for_load_state()

    assert (
        page.locator("#validation .banner-error").inner_text() == "Not valid: 1 error, 0 warnings. Nothing was stored."
    )
    row = page.locator("#validation-issues tbody tr")
    assert row.count() == 1
    assert row.locator(".issue-position").inner_text() == f"Line {issue['line']}, column {issue['column']}"
    assert issue["message"] in row.inner_text()
    assert page.locator("#insert-text").input_value() == BROKEN  # kept for fixing
    page.click("#insert-publish")  # publishing checks again, and stores nothing
    page.wait_for_load_state()
    assert page.locator("#insert-result").count() == 0 and stored(ui_stack) == 0


def test_a_check_shows_what_would_be_added_then_publishing_links_the_receipt(ui_stack: UiStack, page: Any) -> None:
    lobby().publish_all(ui_stack.api_url)
    before = stored(ui_stack)
    maria = "https://example.org/segb/robots/ari/v1/human_maria"
    log = NEW_LOG + f'<{maria}> <http://xmlns.com/foaf/0.1/nick> "Mari" .\n'

    page.goto(f"{ui_stack.ui_url}/logs/insert")
    page.fill("#insert-text", log)
    page.click("#insert-validate")
    page.wait_for_load_state()
    assert page.locator("#validation .banner-success").inner_text() == "Valid: 5 triples checked."
    assert page.locator("#preview-triples").inner_text() == "5"
    assert page.locator("#preview-subjects").inner_text() == "3"
    assert page.locator("#preview-new").inner_text() == "2"  # Maria is already known
    new = page.locator("#preview-new-subjects tbody tr").all_inner_texts()
    assert [row.split("\t")[:2] for row in new] == [["eve", "Eve"], ["zoe", "Zoe"]]
    assert stored(ui_stack) == before  # a check writes nothing

    page.click("#insert-publish")
    page.wait_for_load_state()
    result = page.locator("#insert-result")
    assert result.locator(".banner-success").inner_text() == "Stored: 5 triples received, 5 new."
    assert stored(ui_stack) == before + 5
    receipt = page.locator("#receipt-link").get_attribute("href")
    log_id = receipt.split("#receipt-", 1)[1]
    page.click("#receipt-link")
    page.wait_for_load_state()
    row = page.locator(f"#ledger-receipts tr[id='receipt-{log_id}']")
    assert row.count() == 1 and "ingest" in row.inner_text()
    assert page.console_errors == []


def test_a_file_is_uploaded_checked_and_published(ui_stack: UiStack, page: Any, tmp_path: Path) -> None:
    ntriples = "".join(
        f'<https://example.org/thing/{n}> <http://www.w3.org/2000/01/rdf-schema#label> "thing {n}" .\n'
        for n in range(3)
    )
    upload = tmp_path / "things.nt"
    upload.write_text(ntriples, encoding="utf-8")
    page.goto(f"{ui_stack.ui_url}/logs/insert")
    page.set_input_files("#insert-file", str(upload))
    page.click("#insert-validate")
    page.wait_for_load_state()
    assert page.locator("#insert-text").input_value() == ntriples  # the file's text, ready to publish
    assert page.locator("#preview-new").inner_text() == "3"
    page.click("#insert-publish")
    page.wait_for_load_state()
    assert "3 triples received, 3 new" in page.locator("#insert-result").inner_text()
    assert stored(ui_stack) == 3

    page.fill("#insert-text", ntriples.splitlines()[0] + "\n")
    page.click("#insert-publish")
    page.wait_for_load_state()
    assert page.locator("#insert-result .banner-success").inner_text() == "Stored: 1 triple received, 0 new."


def test_clearing_needs_the_typed_confirmation(ui_stack: UiStack, page: Any) -> None:
    lobby().publish_all(ui_stack.api_url)
    before = stored(ui_stack)
    page.goto(f"{ui_stack.ui_url}/logs/delete")
    assert page.locator("nav a[aria-current=page]").inner_text() == "Clear the graph"
    assert f"The graph holds {before} triples now." in page.inner_text("main")

    page.fill("#clear-confirm", "delete")  # not the word asked for: the browser does not send the form
    page.click("#clear-submit")
    page.wait_for_timeout(300)
    assert page.locator("#clear-result").count() == 0 and stored(ui_stack) == before

    page.fill("#clear-confirm", "DELETE")
    page.click("#clear-submit")
    page.wait_for_load_state()
    assert page.locator("#clear-result .banner-success").inner_text() == f"Removed {before} triples."
    assert stored(ui_stack) == 0
    assert "The graph holds 0 triples now." in page.inner_text("main")
    log_id = page.locator("#receipt-link").get_attribute("href").split("#receipt-", 1)[1]
    receipts = httpx.get(f"{ui_stack.api_url}/ledger", timeout=30).json()["receipts"]
    assert receipts[0]["log_id"] == log_id and receipts[0]["triples_removed"] == before
    assert page.console_errors == []


def test_the_server_refuses_a_wrong_confirmation_and_forms_without_the_csrf_token(ui_stack: UiStack) -> None:
    lobby().publish_all(ui_stack.api_url)
    before = stored(ui_stack)
    with httpx.Client(base_url=ui_stack.ui_url, timeout=30) as client:
        client.get("/logs/delete")
        csrf = client.cookies["segb_csrf"]
        wrong = client.post("/logs/delete", data={"csrf_token": csrf, "confirm": "delete"})
        assert wrong.status_code == 400 and "Type DELETE (in capitals) to confirm" in wrong.text
        forged = client.post("/logs/delete", data={"csrf_token": "forged", "confirm": "DELETE"})
        assert forged.status_code == 403 and "security token" in forged.text
        forged_insert = client.post(
            "/logs/insert", files={"text": (None, NEW_LOG), "action": (None, "publish"), "csrf_token": (None, "x")}
        )
        assert forged_insert.status_code == 403
    assert stored(ui_stack) == before


@pytest.mark.parametrize(("suffix", "fmt"), [("ttl", RdfFormat.TURTLE), ("nt", RdfFormat.N_TRIPLES)])
def test_the_whole_graph_downloads_as_a_stream(ui_stack: UiStack, suffix: str, fmt: RdfFormat) -> None:
    lobby().publish_all(ui_stack.api_url)
    with httpx.stream("GET", f"{ui_stack.ui_url}/export/graph.{suffix}", timeout=60) as answer:
        assert answer.status_code == 200
        assert answer.headers["content-disposition"] == f'attachment; filename="segb-graph.{suffix}"'
        assert "content-length" not in answer.headers  # relayed chunk by chunk, never held whole
        body = b"".join(answer.iter_bytes())
    assert sum(1 for _ in parse(body, fmt)) == stored(ui_stack)


def test_the_whole_graph_downloads_as_json_ld(ui_stack: UiStack) -> None:
    lobby().publish_all(ui_stack.api_url)
    answer = httpx.get(f"{ui_stack.ui_url}/export/graph.jsonld", timeout=60)
    assert answer.status_code == 200 and answer.headers["content-type"].startswith("application/ld+json")
    assert sum(1 for _ in parse(answer.content, RdfFormat.JSON_LD)) == stored(ui_stack)
    assert json.loads(answer.content)


@pytest.fixture
def secured_stack(memory_store: Any) -> Iterator[UiStack]:
    yield from start_ui_stack(memory_store, secret_key=SECRET)


def test_only_admins_reach_the_operator_pages(secured_stack: UiStack) -> None:
    auditor = mint_token(SECRET, username="ann", roles=["auditor"], expires_in=600).token
    admin = mint_token(SECRET, username="root", roles=["admin"], expires_in=600).token
    for path in ("/logs/insert", "/logs/delete"):
        assert httpx.get(secured_stack.ui_url + path, timeout=30).status_code == 401
        refused = httpx.get(secured_stack.ui_url + path, cookies={"segb_token": auditor}, timeout=30)
        assert refused.status_code == 403 and "needs the admin role" in refused.text
        assert httpx.get(secured_stack.ui_url + path, cookies={"segb_token": admin}, timeout=30).status_code == 200
    # The download forwards the viewer's token: without one the API refuses it.
    assert httpx.get(f"{secured_stack.ui_url}/export/graph.ttl", timeout=30).status_code == 401
    with_token = httpx.get(f"{secured_stack.ui_url}/export/graph.ttl", cookies={"segb_token": auditor}, timeout=30)
    assert with_token.status_code == 200
