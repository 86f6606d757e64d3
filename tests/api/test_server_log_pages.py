"""GET /logs/server in pages: `offset` skips that many matching entries, newest first, so a page follows where the
one before ended; a bad offset is a 422."""

from __future__ import annotations

import pytest

from tests.api.test_server_logs import read_log, server  # noqa: F401 (the fixture)
from tests.support.in_process import InProcess


def test_pages_follow_one_another_newest_first(server: InProcess) -> None:  # noqa: F811
    for n in range(7):
        server.get("/healthz/live", headers={"X-Request-ID": f"paged-{n}"})
    ids = [
        [entry["request_id"] for entry in read_log(server, contains="paged-", limit=3, offset=offset).json()["entries"]]
        for offset in (0, 3, 6)
    ]
    assert ids == [["paged-6", "paged-5", "paged-4"], ["paged-3", "paged-2", "paged-1"], ["paged-0"]]
    assert read_log(server, contains="paged-", offset=7).json()["entries"] == []


@pytest.mark.parametrize("offset", [-1, 2001, "later"])
def test_a_bad_offset_is_refused_with_422(server: InProcess, offset: object) -> None:  # noqa: F811
    answer = read_log(server, offset=offset)
    assert answer.status_code == 422 and answer.json()["error"] == "invalid_request"


def test_every_page_counts_the_matching_entries(server: InProcess) -> None:  # noqa: F811
    for n in range(7):
        server.get("/healthz/live", headers={"X-Request-ID": f"counted-{n}"})
    for offset in (0, 3, 6, 9):
        body = read_log(server, contains="counted-", limit=3, offset=offset).json()
        assert (body["total"], body["more"]) == (7, False)
    assert read_log(server, contains="no entry holds this").json()["total"] == 0
