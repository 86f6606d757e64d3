"""The people page in real headless Chromium: its table is padded, each person has a preview of their erasure (what
would go, counted by kind, with nothing written) above the erase form filled in for them, which then erases them;
an IRI the log does not type as a person is refused with the API's reason."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from segb_server.backend.demo import publish_demo
from tests.conftest import UiStack
from tests.support.settle import settle

pytestmark = pytest.mark.browser

CARLOS = "https://example.org/segb/robots/tiago/v1/human_carlos"


def test_a_person_is_previewed_from_their_row_then_erased(ui_stack: UiStack, page: Any) -> None:
    assert "demo dataset published" in publish_demo(ui_stack.api_url)
    settle(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/people")
    cell = page.locator("#people tbody td").first
    assert cell.evaluate("td => parseFloat(getComputedStyle(td).paddingLeft)") >= 4  # not flush against its border
    before = httpx.get(f"{ui_stack.api_url}/ledger").json()["total"]
    events = httpx.get(f"{ui_stack.api_url}/events", params={"format": "ntriples"}).text

    page.locator("#people tbody tr", has_text=CARLOS).get_by_role("button", name="Preview erasure").click()
    page.wait_for_load_state()
    preview = page.locator("#erase-preview")
    assert CARLOS in preview.locator("h2").inner_text()
    kinds = dict(row.locator("td").all_inner_texts() for row in preview.locator("#erase-preview-kinds tbody tr").all())
    assert kinds["human"] == "1" and int(kinds["message"]) >= 1 and int(kinds["emotion"]) >= 1
    assert "nothing has been erased" in preview.inner_text()
    assert page.locator("#erase-iri").input_value() == CARLOS
    assert httpx.get(f"{ui_stack.api_url}/ledger").json()["total"] == before  # the preview wrote nothing
    assert httpx.get(f"{ui_stack.api_url}/events", params={"format": "ntriples"}).text == events

    page.fill("#erase-reason", "Request by the data subject, ticket 9")
    page.fill("#erase-confirm", "ERASE")
    page.click("#erase-submit")
    page.wait_for_load_state()
    assert "Removed" in page.locator("#erase-result .banner-success").inner_text()
    assert page.locator("#people tbody tr", has_text=CARLOS).count() == 0
    assert page.console_errors == []


def test_an_iri_that_is_not_a_person_gets_the_reason_on_the_page(ui_stack: UiStack, page: Any) -> None:
    assert "demo dataset published" in publish_demo(ui_stack.api_url)
    settle(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/people")
    page.fill("#erase-iri", "http://kb.openrobots.org#Human")
    page.click("#erase-preview-submit")
    page.wait_for_load_state()
    assert "is a class or a predicate the log uses" in page.locator(".banner-error").inner_text()
    assert page.locator("#erase-preview").count() == 0
    assert page.locator("#erase-iri").input_value() == "http://kb.openrobots.org#Human"
    assert [error for error in page.console_errors if "422" not in error] == []
    forged = httpx.post(f"{ui_stack.ui_url}/people/preview", data={"iri": CARLOS})  # no CSRF token: refused
    assert forged.status_code == 403
