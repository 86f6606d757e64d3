"""`segb copy-state`: a deployment's journal and shared contexts moved from SQLite in DATA_DIR into PostgreSQL.
The server then started with STATE_URL serves the same receipts, content and contexts, and goes on from them."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from tests.cli.test_cli import segb
from tests.conftest import make_settings
from tests.faults.test_crashes import all_receipts, post_turtle
from tests.support.live_server import LiveServer
from tests.support.net import free_port

pytestmark = pytest.mark.postgres

OBSERVATION = {
    "event_kind": "human_utterance",
    "observed_at": "2026-05-04T10:00:00+00:00",
    "subject_uri": "https://example.org/people/maria",
    "modality": "speech",
    "text": "Good morning, robot!",
}


def post(url: str, robot: int, number: int) -> str:
    answer = httpx.post(f"{url}/ttl", json={"ttl_content": post_turtle(robot, number), "user": "robot"}, timeout=30)
    assert answer.status_code == 201, answer.text
    return str(answer.json()["log_id"])


def resolve(url: str, observation: dict[str, str]) -> dict[str, object]:
    answer = httpx.post(f"{url}/shared-context/resolve", json=observation, timeout=30)
    assert answer.status_code == 200, answer.text
    return dict(answer.json())


def test_the_state_moves_into_postgresql_and_the_server_goes_on_from_it(tmp_path: Path, postgres_url: str) -> None:
    data_dir = tmp_path / "data"  # the embedded store stays there; only the state moves
    before = make_settings(store="oxigraph", data_dir=data_dir)
    with LiveServer(create_app(before)) as live:
        first = post(live.url, 1, 0)
        assert httpx.post(f"{live.url}/ttl/delete_all", json={"user": "admin"}, timeout=30).status_code == 200
        post(live.url, 1, 1)
        context = resolve(live.url, OBSERVATION)["shared_context_uri"]
        receipts = list(all_receipts(live.url))
        content = httpx.get(f"{live.url}/ledger/{first}", timeout=30).json()
        refused = segb("copy-state", "--data-dir", str(data_dir), "--to", postgres_url)
        assert refused.returncode == 2 and "a server is running" in refused.stderr

    copied = segb("copy-state", "--data-dir", str(data_dir), "--to", postgres_url)
    assert copied.returncode == 0, copied.stderr
    assert f"journal: {len(receipts)} rows of receipts" in copied.stdout
    assert f"the copy verifies: {len(receipts)} receipts, content included" in copied.stdout
    again = segb("copy-state", "--data-dir", str(data_dir), "--to", postgres_url)
    assert again.returncode == 2 and "is not empty" in again.stderr

    after = make_settings(store="oxigraph", data_dir=data_dir, state_url=postgres_url)
    with LiveServer(create_app(after)) as live:
        assert list(all_receipts(live.url)) == receipts
        assert httpx.get(f"{live.url}/ledger/{first}", timeout=30).json() == content
        later = post(live.url, 1, 2)
        newest = next(iter(all_receipts(live.url)))
        assert (newest["log_id"], newest["sequence"]) == (later, len(receipts) + 1)  # the chain goes on
        assert httpx.get(f"{live.url}/ledger/verify", params={"deep": "true"}, timeout=30).json()["valid"] is True
        same = resolve(live.url, OBSERVATION)
        assert same["shared_context_uri"] == context and same["status"] == "matched"
        other = resolve(live.url, {**OBSERVATION, "observed_at": "2026-05-05T10:00:00+00:00"})
        assert other["status"] == "created" and other["shared_context_uri"] != context  # new keys follow the copied


def test_copying_into_a_database_that_does_not_answer_fails_naming_it(tmp_path: Path) -> None:
    data_dir = tmp_path / "data"
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=data_dir))) as live:
        post(live.url, 1, 0)
    unreachable = f"postgresql://segb@127.0.0.1:{free_port()}/segb"
    refused = segb("copy-state", "--data-dir", str(data_dir), "--to", unreachable)
    assert refused.returncode == 2
    assert "The state database (postgresql://segb@127.0.0.1:" in refused.stderr and "is unavailable" in refused.stderr
    assert "Traceback" not in refused.stderr
