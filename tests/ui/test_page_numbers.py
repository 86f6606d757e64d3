"""The paged pages (a report, the ledger) read `limit` and `offset` from their URL: anything but a whole number
the API could take is the default, never a server error."""

from __future__ import annotations

import httpx
import pytest

from tests.conftest import UiStack
from tests.support.scenarios import lobby

NOT_PAGE_NUMBERS = {"superscript": "²", "fullwidth digits": "\uff11\uff12", "5000 digits": "9" * 5000, "a word": "ten"}


@pytest.mark.parametrize("path", ["/reports/conversations", "/ledger"])
@pytest.mark.parametrize("name", ["limit", "offset"])
@pytest.mark.parametrize("value", NOT_PAGE_NUMBERS.values(), ids=NOT_PAGE_NUMBERS.keys())
def test_a_page_number_that_is_no_number_is_the_default(ui_stack: UiStack, path: str, name: str, value: str) -> None:
    receipts = lobby().publish_all(ui_stack.api_url)
    answer = httpx.get(f"{ui_stack.ui_url}{path}", params={name: value}, timeout=30)
    assert answer.status_code == 200, answer.text[:300]
    # the first page at its default size: everything published fits it
    shown = [r["log_id"] for r in receipts] if path == "/ledger" else ["Where is the pharmacy?", "Congratulations"]
    assert [text for text in shown if text not in answer.text] == []
