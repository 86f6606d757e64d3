"""The state database (PostgreSQL, STATE_URL) restarted under a running server: while it is away, posts get a
clear 503 that keeps nothing and readiness says why; once it is back the server reconnects by itself, takes
the applier's lock again, and the journal is one valid chain of exactly the acknowledged posts."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.faults.test_crashes import all_receipts, check_consistent, post_turtle
from tests.support.live_server import LiveServer
from tests.support.postgres import PostgresProcess
from tests.support.settle import settle

pytestmark = pytest.mark.postgres


@pytest.fixture
def own_postgres() -> Iterator[PostgresProcess]:
    """A PostgreSQL of this test's own, to stop and start again."""
    process = PostgresProcess()
    process.start()
    yield process
    process.remove()


def post(url: str, turtle: str) -> httpx.Response:
    return httpx.post(f"{url}/ttl", json={"ttl_content": turtle, "user": "robot"}, timeout=30)


def test_a_postgresql_restart_refuses_posts_cleanly_and_the_server_recovers_by_itself(
    own_postgres: PostgresProcess, tmp_path: Path
) -> None:
    url = own_postgres.create_database("segb")
    settings = make_settings(store="oxigraph", data_dir=tmp_path / "data", state_url=url)
    acknowledged: dict[str, str] = {}
    with LiveServer(create_app(settings)) as live:
        first = post(live.url, post_turtle(1, 0))
        assert first.status_code == 201, first.text
        acknowledged[first.json()["log_id"]] = post_turtle(1, 0)

        own_postgres.stop()
        refused = post(live.url, post_turtle(1, 1))
        assert refused.status_code == 503, refused.text
        assert refused.json()["error"] == "state_unavailable"
        assert "state database" in refused.json()["detail"] and refused.headers["Retry-After"]
        ready = httpx.get(f"{live.url}/healthz/ready", timeout=30)
        assert ready.status_code == 503 and ready.json()["journal"] is False
        assert httpx.get(f"{live.url}/healthz/live", timeout=30).status_code == 200

        own_postgres.start()
        second = post(live.url, post_turtle(1, 2))  # answered once applied (INGEST_ACK=store): it leads again
        assert second.status_code == 201, second.text
        acknowledged[second.json()["log_id"]] = post_turtle(1, 2)
        settle(live.url)  # the views, in a process of their own, follow a moment after the acknowledgement
        assert httpx.get(f"{live.url}/healthz/ready", timeout=30).json() == {"ready": True, "oxigraph": True}
        check_consistent(live.url, acknowledged)
        assert [receipt["log_id"] for receipt in all_receipts(live.url)] == [second.json()["log_id"],
                                                                            first.json()["log_id"]]  # fmt: skip
        stored = httpx.get(f"{live.url}/events", params={"format": "ntriples"}, timeout=30).text
        assert "robot 1 post 1 " not in stored  # the refused post left nothing behind
