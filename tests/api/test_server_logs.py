"""The structured server log through the whole app in process: one entry per request (id, user, client, route, status,
duration, triples written), warnings of the server, filters, the rotated file read back newest first, admin-only access,
and the reference backend's answer shape, which its web UI reads."""

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
from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
TURTLE = "<https://example.org/a> a <https://example.org/B> .\n<https://example.org/b> a <https://example.org/B> ."


def bearer(username: str, *roles: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {mint_token(SECRET, username=username, roles=roles).token}"}


ADMIN = bearer("root", "admin")


@pytest.fixture
def server(memory_store: Store) -> Iterator[InProcess]:
    """Authentication on, the log in memory (a STORE=memory server)."""
    with InProcess(create_app(make_settings(secret_key=SECRET), store=memory_store)) as live:
        yield live


def read_log(server: InProcess | LiveServer, **params: object) -> httpx.Response:
    return server.get("/logs/server", params=params, headers=ADMIN)


def test_each_request_is_logged_with_its_id_user_route_status_and_triples(server: InProcess) -> None:
    posted = server.post(
        "/ttl",
        content=TURTLE,
        headers={"Content-Type": "text/turtle", "X-Request-ID": "robot-ari.post-1", **bearer("ari", "logger")},
    )
    assert posted.status_code == 201
    missing = server.get("/reports/nope", headers={"X-Request-ID": "audit-7", **bearer("eve", "auditor")})
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
    assert refused["triples_written"] is None


def test_entries_come_newest_first_and_filter_by_minimum_level(server: InProcess) -> None:
    for n in range(3):
        server.get("/healthz/live", headers={"X-Request-ID": f"order-{n}"})
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
    [{"level": "loud"}, {"limit": 0}, {"limit": 2001}, {"limit": "many"}, {"contains": "x" * 201}],
    ids=["bad level", "limit 0", "limit too big", "limit not a number", "contains too long"],
)
def test_bad_filters_are_refused_with_422(server: InProcess, params: dict[str, object]) -> None:
    answer = read_log(server, **params)
    assert answer.status_code == 422
    assert answer.json()["error"] == "invalid_request"


REFERENCE_KEYS = {"log_file", "count", "filters", "entries"}
REFERENCE_ENTRY_KEYS = {"timestamp", "level", "logger", "request_id", "actor", "origin_ip", "message", "raw"}


def test_the_answer_is_a_superset_of_the_reference_shape(server: InProcess) -> None:
    for n in range(3):
        server.get("/auth/whoami", headers={"X-Request-ID": f"ref-shape-{n}", **bearer("eve", "auditor")})

    # What the reference UI's /system/logs page sends: its row count (up to 2,000), a level, a text.
    answer = read_log(server, limit=2000, level="info", contains="  REF-SHAPE-  ")
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert REFERENCE_KEYS | {"source", "total", "more"} == set(body)
    assert body["log_file"] is None  # kept in memory: there is no file
    assert body["filters"] == {"limit": 2000, "level": "INFO", "contains": "REF-SHAPE-"}  # normalised, trimmed
    assert body["count"] == len(body["entries"]) == 3
    for entry in body["entries"]:
        assert set(entry) >= REFERENCE_ENTRY_KEYS
        assert entry["timestamp"] == entry["time"] and entry["actor"] == entry["user"] == "eve"
        assert entry["origin_ip"] == "127.0.0.1"  # the TCP peer of the request
        raw = json.loads(entry["raw"])
        assert raw == {key: value for key, value in entry.items() if key in raw}
        assert raw["request_id"] == entry["request_id"] and "raw" not in raw
    assert [entry["request_id"] for entry in body["entries"]] == ["ref-shape-2", "ref-shape-1", "ref-shape-0"]


def test_a_blank_level_or_text_is_no_filter_as_the_reference_takes_it(server: InProcess) -> None:
    logging.getLogger("segb.store").info("blank-filter info")
    logging.getLogger("segb.store").warning("blank-filter warning")
    every_level = read_log(server, level="", contains="blank-filter")
    assert every_level.status_code == 200, every_level.text
    assert every_level.json()["filters"]["level"] is None
    assert [entry["level"] for entry in every_level.json()["entries"]] == ["WARNING", "INFO"]
    assert read_log(server, level="warning", contains="blank-filter").json()["count"] == 1
    no_text = read_log(server, contains="   ")
    assert no_text.json()["filters"]["contains"] is None and no_text.json()["count"] > 2


@pytest.fixture
def live_server(memory_store: Store) -> Iterator[LiveServer]:
    """The API over real HTTP: uvicorn decides what a proxy's X-Forwarded-For may say."""
    with LiveServer(create_app(make_settings(secret_key=SECRET), store=memory_store)) as live:
        yield live


def test_the_origin_is_the_peer_or_what_a_trusted_proxy_saw_never_the_first_forwarded_hop(
    live_server: LiveServer,
) -> None:
    server = live_server
    server.get("/healthz/live", headers={"X-Request-ID": "direct-1"})
    # uvicorn trusts X-Forwarded-For only from FORWARDED_ALLOW_IPS (127.0.0.1 by default, as here), and takes
    # the last hop that proxy saw; the first hop, which any client can write (the reference logged it), is not it.
    server.get("/healthz/live", headers={"X-Request-ID": "proxied-1", "X-Forwarded-For": "203.0.113.9, 10.0.0.1"})
    [direct] = read_log(server, contains="direct-1").json()["entries"]
    [proxied] = read_log(server, contains="proxied-1").json()["entries"]
    assert (direct["origin_ip"], proxied["origin_ip"]) == ("127.0.0.1", "10.0.0.1")


def test_only_admins_read_the_log(server: InProcess) -> None:
    assert server.get("/logs/server", headers=bearer("eve", "auditor")).status_code == 403
    assert server.get("/logs/server", headers=bearer("ari", "logger")).status_code == 403
    assert server.get("/logs/server").status_code == 401


@pytest.fixture
def file_server(memory_store: Store, tmp_path: Path) -> Iterator[InProcess]:
    """The log in DATA_DIR/logs/server.jsonl, rotated every ~4 KB, three backups."""
    settings = make_settings(store="oxigraph", data_dir=tmp_path, secret_key=SECRET, server_log_max_bytes=4000)
    with InProcess(create_app(settings, store=memory_store)) as live:
        yield live


def test_the_file_log_rotates_and_is_read_back_across_backups(file_server: InProcess, tmp_path: Path) -> None:
    token = mint_token(SECRET, username="root", roles=["admin"]).token
    for n in range(60):
        file_server.get("/healthz/live", params={"token": token}, headers={"X-Request-ID": f"rot-{n:02d}"})

    log = tmp_path / "logs" / "server.jsonl"
    assert log.exists() and (tmp_path / "logs" / "server.jsonl.1").exists()
    assert all(json.loads(line)["time"] for line in log.read_text().splitlines())
    answer = read_log(file_server, contains="rot-", limit=60)
    assert answer.json()["source"] == "file"
    assert answer.json()["log_file"] == str(log.resolve())
    assert all(json.loads(entry["raw"])["request_id"] == entry["request_id"] for entry in answer.json()["entries"])
    ids = [entry["request_id"] for entry in answer.json()["entries"]]
    assert ids[:3] == ["rot-59", "rot-58", "rot-57"]
    assert len(ids) > 20 and ids == sorted(ids, reverse=True)  # older entries come from the backups
    for path in (tmp_path / "logs").iterdir():
        assert token not in path.read_text()  # the query string (and any header) never reaches the log


def test_lines_that_are_not_log_entries_are_skipped(file_server: InProcess, tmp_path: Path) -> None:
    file_server.get("/healthz/live", headers={"X-Request-ID": "before-damage"})
    with (tmp_path / "logs" / "server.jsonl").open("a", encoding="utf-8") as log:
        log.write('not json\n[1, 2]\n{"level": "INFO", "message": "no time"}\n{"time": 5, "level": "INFO"}\n')
    answer = read_log(file_server, limit=2000)
    assert answer.status_code == 200, answer.text
    assert "before-damage" in [entry["request_id"] for entry in answer.json()["entries"]]
    assert all(isinstance(entry["time"], str) for entry in answer.json()["entries"])


def test_a_record_logged_after_the_log_closed_is_dropped_quietly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # A background thread of a server that is stopping may still log; the file's lock is closed by then.
    from segb_server.backend.services.ops.server_log import ServerLog

    log = ServerLog(tmp_path / "server.jsonl")
    log.handler.handle(logging.LogRecord("segb.views", logging.INFO, __file__, 1, "kept", None, None))
    log.handler.close()
    log.handler.handle(logging.LogRecord("segb.views", logging.INFO, __file__, 1, "late", None, None))
    assert "Logging error" not in capsys.readouterr().err
    lines = (tmp_path / "server.jsonl").read_text().splitlines()
    assert [json.loads(line)["message"] for line in lines] == ["kept"]
