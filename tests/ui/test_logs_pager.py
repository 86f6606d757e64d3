"""The /logs pager: a link to the first and last page and to those near the current one, gaps marked, and no
link past the entries the API reads back."""

from __future__ import annotations

from typing import Any

from segb_server.ui.routes.logs import MAX_OFFSET, pages

WANTED = {"level": "INFO", "contains": "probe"}


def numbers(pager: dict[str, Any]) -> list[str]:
    return [("*" if link["current"] else "") + str(link["number"]) if link else "…" for link in pager["page_links"]]


def test_one_page_has_no_links() -> None:
    assert pages(WANTED, 50, 0, 12, False) == {"previous_href": None, "next_href": None, "page_links": []}


def test_the_pages_near_the_current_one_are_linked_and_the_gaps_marked() -> None:
    pager = pages(WANTED, 10, 100, 400, False)  # page 11 of 40
    assert numbers(pager) == ["1", "…", "9", "10", "*11", "12", "13", "…", "40"]
    assert pager["previous_href"] == "?level=INFO&contains=probe&limit=10&offset=90"
    assert pager["next_href"] == "?level=INFO&contains=probe&limit=10&offset=110"


def test_the_last_page_has_no_older_one() -> None:
    pager = pages(WANTED, 50, 150, 153, False)
    assert numbers(pager) == ["1", "2", "3", "*4"] and pager["next_href"] is None


def test_no_page_past_the_entries_the_api_reads_back_is_linked() -> None:
    pager = pages(WANTED, 500, MAX_OFFSET, MAX_OFFSET + 500, True)  # more than 2,500 entries match
    assert numbers(pager) == ["1", "2", "3", "4", "*5"]  # offsets 0 to 2,000
    assert pager["next_href"] is None
