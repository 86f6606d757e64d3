"""/ledger in real headless Chromium: the receipts, the chain's state, paging, and hostile text kept as text."""

from __future__ import annotations

import re
import sqlite3
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store
from segb_server.ui.app import create_ui_app
from tests.conftest import UiStack, make_settings
from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby

pytestmark = pytest.mark.browser

HOSTILE = '<script>window.__pwned = 1</script><img src=x onerror="window.__pwned = 2">'
SHA256 = re.compile(r"^[0-9a-f]{64}$")


@pytest.fixture
def disk_ledger_stack(memory_store: Store, tmp_path: Path) -> Iterator[UiStack]:
    """The UI over an API whose ledger is a file (the store itself stays in memory)."""
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path), store=memory_store)) as api:
        ui_settings = make_settings(backend_url=api.url)
        with LiveServer(create_ui_app(ui_settings)) as ui:
            yield UiStack(api, ui, memory_store)


def post_raw(api_url: str, text: str, user: str) -> dict:
    answer = httpx.post(
        f"{api_url}/ttl", content=text, params={"user": user}, headers={"Content-Type": "text/turtle"}, timeout=60
    )
    assert answer.status_code == 201, answer.text
    return answer.json()


def test_ledger_page_shows_the_receipts_under_an_intact_chain(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    responses = lobby().publish_all(ui_stack.api_url)
    post_raw(ui_stack.api_url, "<https://example.org/a> a <https://example.org/B> .", HOSTILE)
    total = len(responses) + 1

    page.goto(f"{ui_stack.ui_url}/ledger")

    assert page.locator("h1").inner_text() == "Ingest ledger"
    assert page.locator("nav a[aria-current=page]").inner_text() == "Ledger"
    assert page.locator(".banner-success").inner_text() == f"Chain intact: {total} receipts"
    rows = page.locator("#ledger-receipts tbody tr")
    assert rows.count() == total
    newest = rows.first
    assert newest.get_attribute("data-sequence") == str(total)
    assert HOSTILE in newest.inner_text()  # the claimed user, shown as text
    assert page.evaluate("window.__pwned") is None
    oldest = rows.last.locator("td")
    assert oldest.nth(2).inner_text() == "ingest"
    assert oldest.nth(4).inner_text() == "ari"
    assert oldest.nth(5).inner_text() == str(responses[0]["triples_received"])
    full = rows.last.locator("code.payload-hash").get_attribute("title")
    assert SHA256.match(full or "")
    assert rows.last.locator("code.payload-hash").inner_text() == full[:10] + "…"
    assert page.console_errors == []


def test_ledger_page_pages_through_the_receipts(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    lobby().publish_all(ui_stack.api_url)  # ten posts

    page.goto(f"{ui_stack.ui_url}/ledger?limit=4")
    sequences = page.locator("#ledger-receipts tbody tr").evaluate_all("rows => rows.map(r => r.dataset.sequence)")
    assert sequences == ["10", "9", "8", "7"]
    assert page.get_by_role("link", name="Previous 4").count() == 0
    page.get_by_role("link", name="Next 4").click()
    page.wait_for_load_state()
    assert "offset=4" in page.url
    assert page.locator("#ledger-receipts tbody tr").first.get_attribute("data-sequence") == "6"
    page.get_by_role("link", name="Next 4").click()
    page.wait_for_load_state()
    assert page.locator("#ledger-receipts tbody tr").count() == 2
    assert page.get_by_role("link", name="Next 4").count() == 0
    assert "Showing 9\u201310 of 10" in page.locator("nav.pager").inner_text()
    page.get_by_role("link", name="Previous 4").click()
    page.wait_for_load_state()
    assert page.locator("#ledger-receipts tbody tr").first.get_attribute("data-sequence") == "6"
    assert page.console_errors == []


def test_ledger_page_names_the_first_broken_receipt(disk_ledger_stack: UiStack, tmp_path: Path, page) -> None:  # type: ignore[no-untyped-def]
    documents = [f"<https://example.org/i{n}> a <https://example.org/T> ." for n in range(4)]
    log_ids = [post_raw(disk_ledger_stack.api_url, document, "ari")["log_id"] for document in documents]
    with sqlite3.connect(tmp_path / "journal.sqlite3") as connection:
        connection.execute("UPDATE receipts SET claimed_user = 'mallory' WHERE sequence = 2")

    page.goto(f"{disk_ledger_stack.ui_url}/ledger")

    alert = page.locator(".banner-error").inner_text()
    assert "Chain broken at receipt 2" in alert and log_ids[1] in alert and "hash mismatch" in alert
    assert page.locator(".banner-success").count() == 0
    broken_row = page.locator("#ledger-receipts tr[data-sequence='2']")
    assert "broken" in broken_row.inner_text()
    assert page.console_errors == []


def test_ledger_page_is_empty_before_any_post(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_stack.ui_url}/ledger")
    assert page.locator(".banner-success").inner_text() == "Chain intact: 0 receipts"
    assert "nothing has been published" in page.locator(".empty").inner_text()
    assert page.console_errors == []
