"""The server's SQLite files (the journal, every view) do not keep a write-ahead log at the largest size one
transaction made it: after a big post, the next post's commits truncate each log to WAL_KEPT_BYTES. Served in
process, and by `segb serve` as a process of its own."""

from __future__ import annotations

from pathlib import Path

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.state.sqlite import WAL_KEPT_BYTES
from tests.conftest import make_settings
from tests.faults.test_crashes import Server as ServerProcess
from tests.support.in_process import InProcess, Server, http
from tests.support.settle import settle

NTRIPLES = {"Content-Type": "application/n-triples"}


def big_post(things: int) -> str:
    return "".join(
        f"<https://example.org/things/thing-{n}> <https://example.org/links/to> <https://example.org/things/o-{n}> .\n"
        f'<https://example.org/things/thing-{n}> <https://example.org/links/label> "thing number {n}" .\n'
        for n in range(things)
    )


def logs(data_dir: Path) -> dict[str, int]:
    return {path.name: path.stat().st_size for path in data_dir.glob("*.sqlite3-wal")}


def big_post_then_a_small_one(server: Server, data_dir: Path) -> None:
    settle(server)
    assert http(server, "POST", "/ttl", content=big_post(20_000), headers=NTRIPLES).status_code == 201
    settle(server, timeout=300)
    grown = {name: size for name, size in logs(data_dir).items() if size > WAL_KEPT_BYTES}
    assert grown, f"no log outgrew {WAL_KEPT_BYTES} bytes: the post is too small to tell ({logs(data_dir)})"

    small = '<https://example.org/things/a> <https://example.org/links/label> "small" .\n'
    assert http(server, "POST", "/ttl", content=small, headers=NTRIPLES).status_code == 201
    settle(server)
    after = logs(data_dir)
    assert all(after[name] <= WAL_KEPT_BYTES for name in grown), {name: after[name] for name in grown}
    # Nothing the big post wrote into the graph index went with the logs' pages.
    params = {"focus": "https://example.org/things/thing-19999", "depth": 1}
    focus = http(server, "GET", "/graph", params=params).json()
    assert "https://example.org/things/o-19999" in {node["id"] for node in focus["nodes"]}


def test_a_big_posts_write_ahead_logs_are_cut_back_by_the_next_post(tmp_path: Path) -> None:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as api:
        big_post_then_a_small_one(api.client, tmp_path)


@pytest.mark.processes
def test_a_served_big_posts_write_ahead_logs_are_cut_back_by_the_next_post(tmp_path: Path) -> None:
    server = ServerProcess(tmp_path / "data")
    server.start()
    try:
        big_post_then_a_small_one(server.url, server.data_dir)
    finally:
        server.stop()
