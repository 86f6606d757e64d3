"""The ingest ledger through the whole app, served in process: receipts match what was posted, the chain verifies,
tampering with the SQLite file is caught at the first broken receipt, the chain survives a restart and concurrent
posts."""

from __future__ import annotations

import gzip
import hashlib
import json
import sqlite3
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from tests.conftest import make_settings
from tests.support.in_process import InProcess, Server, http, publisher_for
from tests.support.scenarios import lobby

GENESIS = "0" * 64
SECRET = "ledger-test-secret-of-at-least-32-characters"


def turtle(index: int) -> str:
    return (
        "@prefix ex: <https://example.org/ledger/> .\n"
        f'ex:item{index} a ex:Thing ; ex:index {index} ; ex:label "item {index}" .\n'
    )


def post_turtle(server: Server, text: str, *, user: str | None = None, token: str | None = None) -> dict:
    headers = {"Content-Type": "text/turtle"}
    if token:
        headers["Authorization"] = f"Bearer {token}"
    params = {"user": user} if user else None
    answer = http(server, "POST", "/ttl", content=text.encode("utf-8"), headers=headers, params=params)
    assert answer.status_code == 201, answer.text
    return answer.json()


def all_receipts(server: Server, token: str | None = None) -> list[dict]:
    """Every receipt, oldest first."""
    headers = {"Authorization": f"Bearer {token}"} if token else None
    answer = http(server, "GET", "/ledger", params={"limit": 1000}, headers=headers)
    assert answer.status_code == 200, answer.text
    return list(reversed(answer.json()["receipts"]))


def verify(server: Server) -> dict:
    answer = http(server, "GET", "/ledger/verify")
    assert answer.status_code == 200, answer.text
    return answer.json()


def expected_hash(receipt: dict) -> str:
    """The documented formula, computed independently of the server's code."""
    covered = {key: value for key, value in receipt.items() if key != "receipt_hash"}
    return hashlib.sha256(json.dumps(covered, sort_keys=True, separators=(",", ":")).encode("utf-8")).hexdigest()


def assert_chained(receipts: list[dict]) -> None:
    assert [receipt["sequence"] for receipt in receipts] == list(range(1, len(receipts) + 1))
    previous = GENESIS
    for receipt in receipts:
        assert receipt["previous_hash"] == previous
        assert receipt["receipt_hash"] == expected_hash(receipt)
        previous = receipt["receipt_hash"]


@pytest.fixture
def disk_api(tmp_path: Path) -> Iterator[InProcess]:
    """An API that opens its own on-disk store, so the journal is the file `<data_dir>/journal.sqlite3`."""
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        yield server


def test_receipts_match_a_mixed_run_of_posts(memory_api: InProcess) -> None:
    scenario = lobby()
    publishers = {name: publisher_for(memory_api.client, name) for name in scenario.loggers}
    sent: list[tuple[str, dict]] = []  # (SHA-256 of the Turtle sent, response), in posting order

    def publish(robot: str) -> None:
        # Exactly what `SemanticSEGBLogger.publish` sends: the robot's whole graph as Turtle.
        text = scenario.loggers[robot].graph.serialize(format="turtle")
        sent.append((hashlib.sha256(text.encode("utf-8")).hexdigest(), publishers[robot].publish_turtle(text)))

    scenario.run_steps(publish)
    raw = turtle(1)
    first_raw = post_turtle(memory_api.client, raw, user="maria")
    again = post_turtle(memory_api.client, raw)
    assert again["triples_new"] == 0
    zipped = memory_api.post(
        "/ttl",
        content=gzip.compress(turtle(2).encode("utf-8")),
        headers={"Content-Type": "text/turtle", "Content-Encoding": "gzip"},
    )
    assert zipped.status_code == 201
    sent += [(hashlib.sha256(raw.encode()).hexdigest(), first_raw), (hashlib.sha256(raw.encode()).hexdigest(), again)]
    sent.append((hashlib.sha256(turtle(2).encode()).hexdigest(), zipped.json()))  # hashed after gzip decoding
    cleared = publishers["ari"].delete_all_ttls()

    receipts = all_receipts(memory_api.client)
    assert len(receipts) == len(sent) + 1
    for receipt, (payload_sha256, response) in zip(receipts, sent, strict=False):
        assert receipt["action"] == "ingest"
        assert receipt["log_id"] == response["log_id"]
        assert receipt["payload_sha256"] == payload_sha256
        assert receipt["triples_received"] == response["triples_received"]
        assert receipt["triples_new"] == response["triples_new"]
        assert receipt["triples_removed"] == 0
        assert receipt["user"] == response["user"] == "anonymous_user"
        assert receipt["claimed_user"] == response["claimed_user"]
        assert receipt["recorded_at"].endswith("Z")
    assert [receipt["claimed_user"] for receipt in receipts[: len(scenario.steps)]] == [
        robot for robot, _ in scenario.steps
    ]
    assert receipts[len(scenario.steps)]["claimed_user"] == "maria"
    assert receipts[len(scenario.steps) + 1]["triples_new"] == 0
    deletion = receipts[-1]
    assert deletion["action"] == "delete_all"
    assert deletion["log_id"] == cleared["log_id"]
    assert deletion["triples_removed"] == cleared["triples_removed"] > 0
    assert deletion["claimed_user"] == "ari"
    assert deletion["payload_sha256"] == hashlib.sha256(b"").hexdigest()
    assert_chained(receipts)
    assert verify(memory_api.client) == {"valid": True, "receipts": len(receipts)}


def test_ledger_pages_newest_first_and_checks_its_parameters(memory_api: InProcess) -> None:
    for index in range(5):
        post_turtle(memory_api.client, turtle(index))
    page = memory_api.get("/ledger", params={"limit": 2, "offset": 1}).json()
    assert [receipt["sequence"] for receipt in page["receipts"]] == [4, 3]
    assert (page["total"], page["limit"], page["offset"]) == (5, 2, 1)
    assert memory_api.get("/ledger").json()["limit"] == 100
    for bad in ({"limit": 0}, {"limit": 1001}, {"offset": -1}):
        assert memory_api.get("/ledger", params=bad).status_code == 422


def test_an_empty_ledger_verifies(memory_api: InProcess) -> None:
    assert verify(memory_api.client) == {"valid": True, "receipts": 0}
    assert memory_api.get("/ledger").json() == {"receipts": [], "total": 0, "limit": 100, "offset": 0}


def test_receipts_name_the_authenticated_user_and_need_the_auditor_role(memory_store) -> None:  # type: ignore[no-untyped-def]
    logger = mint_token(SECRET, username="ari-bot", roles=["logger"]).token
    auditor = mint_token(SECRET, username="inspector", roles=["auditor"]).token
    with InProcess(create_app(make_settings(secret_key=SECRET), store=memory_store)) as server:
        post_turtle(server.client, turtle(1), user="somebody-else", token=logger)
        assert server.get("/ledger").status_code == 401
        for path in ("/ledger", "/ledger/verify"):
            assert server.get(f"{path}", headers={"Authorization": f"Bearer {logger}"}).status_code == 403
        (receipt,) = all_receipts(server.client, token=auditor)
    assert (receipt["user"], receipt["claimed_user"]) == ("ari-bot", "somebody-else")


def test_a_memory_server_writes_no_ledger_file(tmp_path: Path) -> None:
    with InProcess(create_app(make_settings(store="memory", data_dir=tmp_path))) as server:
        post_turtle(server.client, turtle(1))
        assert len(all_receipts(server.client)) == 1
    assert not (tmp_path / "journal.sqlite3").exists()


def tamper(ledger_file: Path, statement: str) -> None:
    """Edit the ledger behind the server's back, as someone with access to the file could."""
    with sqlite3.connect(ledger_file) as connection:
        assert connection.execute(statement).rowcount == 1


def test_an_edited_receipt_is_a_hash_mismatch(disk_api: InProcess, tmp_path: Path) -> None:
    log_ids = [post_turtle(disk_api.client, turtle(index))["log_id"] for index in range(5)]
    assert verify(disk_api.client) == {"valid": True, "receipts": 5}

    tamper(tmp_path / "journal.sqlite3", "UPDATE receipts SET triples_new = triples_new + 1 WHERE sequence = 3")

    assert verify(disk_api.client) == {
        "valid": False,
        "receipts": 5,
        "first_broken": {"sequence": 3, "log_id": log_ids[2], "reason": "hash mismatch"},
    }


def test_an_edit_with_a_recomputed_hash_breaks_the_next_link(disk_api: InProcess, tmp_path: Path) -> None:
    log_ids = [post_turtle(disk_api.client, turtle(index))["log_id"] for index in range(4)]
    forged = {**all_receipts(disk_api.client)[1], "triples_new": 0}
    forged["receipt_hash"] = expected_hash(forged)

    tamper(
        tmp_path / "journal.sqlite3",
        f"UPDATE receipts SET triples_new = 0, receipt_hash = '{forged['receipt_hash']}' WHERE sequence = 2",
    )

    assert verify(disk_api.client)["first_broken"] == {
        "sequence": 3,
        "log_id": log_ids[2],
        "reason": "previous hash does not match",
    }


def test_a_deleted_receipt_is_a_sequence_gap(disk_api: InProcess, tmp_path: Path) -> None:
    log_ids = [post_turtle(disk_api.client, turtle(index))["log_id"] for index in range(5)]

    tamper(tmp_path / "journal.sqlite3", "DELETE FROM receipts WHERE sequence = 3")

    assert verify(disk_api.client) == {
        "valid": False,
        "receipts": 4,
        "first_broken": {"sequence": 4, "log_id": log_ids[3], "reason": "sequence gap"},
    }


def test_the_chain_survives_a_restart_and_keeps_growing(tmp_path: Path) -> None:
    settings = make_settings(store="oxigraph", data_dir=tmp_path)
    with InProcess(create_app(settings)) as first:
        for index in range(3):
            post_turtle(first.client, turtle(index))
        before = all_receipts(first.client)

    with InProcess(create_app(settings)) as second:
        assert all_receipts(second.client) == before
        republished = post_turtle(second.client, turtle(0))  # the store kept its triples too
        post_turtle(second.client, turtle(3))
        after = all_receipts(second.client)
        verified = verify(second.client)

    assert republished["triples_new"] == 0
    assert after[:3] == before
    assert after[3]["previous_hash"] == before[-1]["receipt_hash"]
    assert after[3]["log_id"] == republished["log_id"]
    assert_chained(after)
    assert verified == {"valid": True, "receipts": 5}


def test_concurrent_posts_keep_one_chain(disk_api: InProcess) -> None:
    with ThreadPoolExecutor(max_workers=8) as pool:
        responses = list(pool.map(lambda index: post_turtle(disk_api.client, turtle(index)), range(32)))

    receipts = all_receipts(disk_api.client)
    assert sorted(receipt["log_id"] for receipt in receipts) == sorted(response["log_id"] for response in responses)
    assert_chained(receipts)
    assert verify(disk_api.client) == {"valid": True, "receipts": 32}
