"""The people page in real headless Chromium: a person's data read as a page, then erased after typing ERASE;
a wrong confirmation erases nothing; the names the robots logged are shown as text, never as markup."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.conftest import UiStack
from tests.support.people import INES_NAME, INES_SAYS, care_home

pytestmark = pytest.mark.browser


def test_a_person_is_read_then_erased_after_a_typed_confirmation(ui_stack: UiStack, page: Any) -> None:
    visit = care_home()
    visit.publish_steps(ui_stack.api_url)
    ines = str(visit.iris["ines"])
    page.goto(f"{ui_stack.ui_url}/people")
    assert page.locator("nav a[aria-current=page]").inner_text() == "People"
    row = page.locator("#people tbody tr", has_text=ines)
    assert row.locator("td").first.inner_text() == INES_NAME

    page.goto(ui_stack.ui_url + row.locator("a", has_text="read").get_attribute("href"))
    assert f"{INES_NAME} said to ARI: “{INES_SAYS[0]}”" in page.locator("body").inner_text()
    assert page.locator("script").count() == 0

    page.goto(f"{ui_stack.ui_url}/people")
    page.fill("#erase-iri", ines)
    page.fill("#erase-reason", "Request by the data subject, ticket 7")
    page.fill("#erase-confirm", "erase")  # not in capitals: the browser's own check refuses it first
    page.evaluate("document.querySelector('#erase-form').noValidate = true")
    page.click("#erase-submit")
    page.wait_for_load_state()
    assert "Nothing was erased" in page.locator(".banner-error").inner_text()
    assert httpx.get(f"{ui_stack.api_url}/ledger").json()["total"] == len(visit.steps)

    page.fill("#erase-confirm", "ERASE")
    page.click("#erase-submit")
    page.wait_for_load_state()
    assert "Removed" in page.locator("#erase-result .banner-success").inner_text()
    log_id = page.locator("#erasure-receipt").get_attribute("href").rsplit("receipt-", 1)[1]
    receipt = httpx.get(f"{ui_stack.api_url}/ledger/{log_id}").json()
    assert receipt["receipt"]["action"] == "erase" and receipt["redaction"]["reason"].endswith("ticket 7")
    assert page.locator("#people tbody tr", has_text=ines).count() == 0
    page.click("#erasure-receipt")
    page.wait_for_load_state()
    assert "with 1 erasure" in page.locator(".banner-success").inner_text()
    assert page.locator(f"#receipt-{log_id} td").nth(6).inner_text().endswith("removed")
    # The one error is the wrong confirmation's answer (a 400 page).
    assert [error for error in page.console_errors if "400 (Bad Request)" not in error] == []


def test_a_hostile_name_is_shown_as_text_on_the_page_and_in_the_export(ui_stack: UiStack, page: Any) -> None:
    hostile = '<img src=x onerror="document.title=1">Eve'
    turtle = (
        "<https://example.org/h/eve> a <http://kb.openrobots.org#Human> ; <http://xmlns.com/foaf/0.1/firstName> "
        f'"{hostile.replace(chr(34), chr(92) + chr(34))}" .'
    )
    assert httpx.post(f"{ui_stack.api_url}/ttl", json={"ttl_content": turtle}).status_code == 201
    page.goto(f"{ui_stack.ui_url}/people")
    assert page.locator("#people tbody td", has_text="Eve").first.inner_text() == hostile
    page.goto(f"{ui_stack.ui_url}/people/export?iri=https%3A%2F%2Fexample.org%2Fh%2Feve&format=html")
    assert hostile in page.locator("h1").inner_text() and page.locator("img").count() == 0
    assert page.title() != "1"
