"""The server's SQLite files (the journal, every view) do not keep a write-ahead log at the largest size one
transaction made it: after a big post, the next post's commits truncate each log to WAL_KEPT_BYTES."""

from __future__ import annotations

from pathlib import Path

from segb_server.backend.api.app import create_app
from segb_server.backend.state.sqlite import WAL_KEPT_BYTES
from tests.conftest import make_settings
from tests.support.in_process import InProcess
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


def test_a_big_posts_write_ahead_logs_are_cut_back_by_the_next_post(tmp_path: Path) -> None:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as api:
        settle(api.client)
        assert api.post("/ttl", content=big_post(20_000), headers=NTRIPLES).status_code == 201
        settle(api.client, timeout=300)
        grown = {name: size for name, size in logs(tmp_path).items() if size > WAL_KEPT_BYTES}
        assert grown, f"no log outgrew {WAL_KEPT_BYTES} bytes: the post is too small to tell ({logs(tmp_path)})"

        small = '<https://example.org/things/a> <https://example.org/links/label> "small" .\n'
        assert api.post("/ttl", content=small, headers=NTRIPLES).status_code == 201
        settle(api.client)
        after = logs(tmp_path)
        assert all(after[name] <= WAL_KEPT_BYTES for name in grown), {name: after[name] for name in grown}
        # Nothing the big post wrote into the graph index went with the logs' pages.
        focus = api.get("/graph", params={"focus": "https://example.org/things/thing-19999", "depth": 1}).json()
        assert "https://example.org/things/o-19999" in {node["id"] for node in focus["nodes"]}
