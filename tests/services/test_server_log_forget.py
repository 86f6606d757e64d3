"""The server log forgetting an erased person, in a file with its rotation: every spelling of their IRI goes (as
written, percent-encoded wholly or in part, and the path a request naming it is logged as), other lines stay."""

from __future__ import annotations

import logging
from pathlib import Path
from urllib.parse import quote

import pytest

from segb_server.backend.api.request_context import logged_path
from segb_server.backend.services.ops.server_log import ServerLog

MARIA = "https://example.org/segb/robots/ari/v1/human_maria"
NAMING_HER = {
    "as written": f"request path=/no-such-page/{MARIA} status=404",
    "percent-encoded": f"request path=/ledger/{quote(MARIA, safe='')} status=404",
    "partly encoded": f"request path=/ledger/{quote(MARIA)} status=404",
    "encoded twice": f"request path=/ledger/{quote(quote(MARIA, safe=''), safe='')} status=404",
    "the path form": f"request path={logged_path('/humans/' + MARIA)} status=404",
    "the path form, encoded": f"request path={logged_path('/humans/' + quote(MARIA, safe=''))} status=404",
}
KEPT = (
    f"request path={logged_path('/humans/https://example.org/segb/robots/ari/v1/human_mariano')} status=404",
    "request path=/humans/erase status=200",
    f"request path={logged_path('/humans/' + MARIA + '/export')} status=200",  # the export's path names no one
)


@pytest.fixture
def server_log(tmp_path: Path) -> ServerLog:
    log = ServerLog(tmp_path / "server.jsonl", max_bytes=10_000_000, backups=1)
    log.install()
    yield log  # type: ignore[misc]
    log.uninstall()


def test_every_spelling_of_an_erased_iri_is_forgotten(server_log: ServerLog) -> None:
    assert "/humans/{iri}/human_maria" in NAMING_HER["the path form"]
    writer = logging.getLogger("segb.requests")
    for line in (*NAMING_HER.values(), *KEPT):
        writer.warning(line)
    assert server_log.forget([MARIA], []) == len(NAMING_HER)
    left = [entry["message"] for entry in server_log.read(100)]
    assert sorted(left) == sorted(KEPT)
