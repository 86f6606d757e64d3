"""The structured server log over real HTTP: one entry per request (id, user, route, status, duration, triples
written), warnings of the server, filters, the rotated file read back newest first, and admin-only access."""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from segb_server.backend.store.base import Store
from tests.conftest import make_settings
from tests.support.live_server import LiveServer

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
TURTLE = "<https://example.org/a> a <https://example.org/B> .\n<https://example.org/b> a <https://example.org/B> ."


def bearer(username: str, *roles: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {mint_token(SECRET, username=username, roles=roles).token}"}


ADMIN = bearer("root", "admin")


@pytest.fixture
def server(memory_store: Store) -> Iterator[LiveServer]:
    """Authentication on, the log in memory (a STORE=memory server)."""
    with LiveServer(create_app(make_settings(secret_key=SECRET), store=memory_store)) as live:
        yield live


def read_log(server: LiveServer, **params: object) -> httpx.Response:
    return httpx.get(f"{server.url}/logs/server", params=params, headers=ADMIN, timeout=30)


def test_each_request_is_logged_with_its_id_user_route_status_and_triples(server: LiveServer) -> None:
    posted = httpx.post(
        f"{server.url}/ttl",
        content=TURTLE,
        headers={"Content-Type": "text/turtle", "X-Request-ID": "robot-ari.post-1", **bearer("ari", "logger")},
    )
    assert posted.status_code == 201
    missing = httpx.get(f"{server.url}/reports/nope", headers={"X-Request-ID": "audit-7", **bearer("eve", "auditor")})
    assert missing.status_code == 404

    answer = read_log(server, contains="robot-ari.post-1")
    assert answer.status_code == 200, answer.text
    assert answer.json()["source"] == "memory"
    [entry] = answer.json()["entries"]
    assert entry["logger"] == "segb.requests" and entry["level"] == "INFO"
    assert (entry["method"], entry["path"], entry["status"], entry["user"]) == ("POST", "/ttl", 201, "ari")
    assert entry["triples_written"] == 2 and entry["duration_ms"] >= 0
    assert entry["time"].endswith("Z")
    assert "triples_written=2" in entry["message"]
    assert entry["log_id"] == posted.json()["log_id"]  # the same id as in the answer and the ledger

    [refused] = read_log(server, contains="AUDIT-7").json()["entries"]  # any case
    assert (refused["path"], refused["status"], refused["user"]) == ("/reports/nope", 404, "eve")
    assert "triples_written" not in refused


def test_entries_come_newest_first_and_filter_by_minimum_level(server: LiveServer) -> None:
    for n in range(3):
        httpx.get(f"{server.url}/healthz/live", headers={"X-Request-ID": f"order-{n}"})
    logging.getLogger("segb.store").warning("store lost: order-test")
    logging.getLogger("segb.api").error("store error on GET /graph: order-test")

    ids = [entry["request_id"] for entry in read_log(server, contains="order-", level="INFO").json()["entries"][2:]]
    assert ids == ["order-2", "order-1", "order-0"]
    warnings = read_log(server, level="warning", contains="order-test").json()["entries"]
    assert [(e["level"], e["logger"]) for e in warnings] == [("ERROR", "segb.api"), ("WARNING", "segb.store")]
    assert [e["level"] for e in read_log(server, level="ERROR", contains="order-test").json()["entries"]] == ["ERROR"]
    assert len(read_log(server, limit=2).json()["entries"]) == 2


@pytest.mark.parametrize(
    "params",
    [{"level": "loud"}, {"limit": 0}, {"limit": 1001}, {"limit": "many"}, {"contains": "x" * 201}],
    ids=["bad level", "limit 0", "limit too big", "limit not a number", "contains too long"],
)
def test_bad_filters_are_refused_with_422(server: LiveServer, params: dict[str, object]) -> None:
    answer = read_log(server, **params)
    assert answer.status_code == 422
    assert answer.json()["error"] == "invalid_request"


def test_only_admins_read_the_log(server: LiveServer) -> None:
    assert httpx.get(f"{server.url}/logs/server", headers=bearer("eve", "auditor")).status_code == 403
    assert httpx.get(f"{server.url}/logs/server", headers=bearer("ari", "logger")).status_code == 403
    assert httpx.get(f"{server.url}/logs/server").status_code == 401


@pytest.fixture
def file_server(memory_store: Store, tmp_path: Path) -> Iterator[LiveServer]:
    """The log in DATA_DIR/logs/server.jsonl, rotated every ~4 KB, three backups."""
    settings = make_settings(store="oxigraph", data_dir=tmp_path, secret_key=SECRET, server_log_max_bytes=4000)
    with LiveServer(create_app(settings, store=memory_store)) as live:
        yield live


def test_the_file_log_rotates_and_is_read_back_across_backups(file_server: LiveServer, tmp_path: Path) -> None:
    token = mint_token(SECRET, username="root", roles=["admin"]).token
    for n in range(60):
        httpx.get(f"{file_server.url}/healthz/live", params={"token": token}, headers={"X-Request-ID": f"rot-{n:02d}"})

    log = tmp_path / "logs" / "server.jsonl"
    assert log.exists() and (tmp_path / "logs" / "server.jsonl.1").exists()
    assert all(json.loads(line)["time"] for line in log.read_text().splitlines())
    answer = read_log(file_server, contains="rot-", limit=60)
    assert answer.json()["source"] == "file"
    ids = [entry["request_id"] for entry in answer.json()["entries"]]
    assert ids[:3] == ["rot-59", "rot-58", "rot-57"]
    assert len(ids) > 20 and ids == sorted(ids, reverse=True)  # older entries come from the backups
    for path in (tmp_path / "logs").iterdir():
        assert token not in path.read_text()  # the query string (and any header) never reaches the log
