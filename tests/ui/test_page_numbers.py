"""The paged pages (a report, the ledger) read `limit` and `offset` from their URL: anything but a whole number
the API could take is the default, never a server error."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.in_process import UiOverApi
from tests.support.scenarios import lobby

NOT_PAGE_NUMBERS = {"superscript": "²", "fullwidth digits": "\uff11\uff12", "5000 digits": "9" * 5000, "a word": "ten"}


@pytest.fixture(scope="module")
def published() -> Iterator[tuple[UiOverApi, list[dict]]]:
    """The UI over an API holding the lobby scenario (the pages only read it), and the receipts of its posts."""
    store = OxigraphStore("http://amor-segb/events")
    settings = make_settings()
    with UiOverApi(create_app(settings, store=store), settings) as served:
        yield served, lobby().publish_all(served.api)
    store.close()


@pytest.mark.parametrize("path", ["/reports/conversations", "/ledger"])
@pytest.mark.parametrize("name", ["limit", "offset"])
@pytest.mark.parametrize("value", NOT_PAGE_NUMBERS.values(), ids=NOT_PAGE_NUMBERS.keys())
def test_a_page_number_that_is_no_number_is_the_default(
    published: tuple[UiOverApi, list[dict]], path: str, name: str, value: str
) -> None:
    ui, receipts = published
    answer = ui.get(path, params={name: value})
    assert answer.status_code == 200, answer.text[:300]
    # the first page at its default size: everything published fits it
    shown = [r["log_id"] for r in receipts] if path == "/ledger" else ["Where is the pharmacy?", "Congratulations"]
    assert [text for text in shown if text not in answer.text] == []
