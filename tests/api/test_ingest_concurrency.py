"""Many robots posting at once to the on-disk store, through the whole app in process: overlapping graphs are counted
exactly once, every answered post already has its receipt, and the ledger chain stays whole."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from pyoxigraph import RdfFormat, parse

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.in_process import InProcess

ROBOTS = 16
POSTS_PER_ROBOT = 6


def payload(robot: int, post: int) -> str:
    # Each post repeats a shared description every robot also sends, so concurrent posts overlap.
    return (
        "@prefix ex: <https://example.org/crowd/> .\n"
        'ex:lobby a ex:Place ; ex:label "the lobby" .\n'
        f"ex:robot{robot} a ex:Robot ; ex:in ex:lobby .\n"
        f'ex:event{robot}-{post} a ex:Event ; ex:by ex:robot{robot} ; ex:index {post} ; ex:label "event {post}" .\n'
    )


@pytest.fixture
def disk_api(tmp_path: Path) -> Iterator[InProcess]:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        yield server


def test_concurrent_overlapping_posts_count_each_triple_once_and_are_receipted_before_the_answer(
    disk_api: InProcess, tmp_path: Path
) -> None:
    ledger_file = tmp_path / "journal.sqlite3"

    def robot(index: int) -> list[tuple[dict, bool]]:
        seen = []
        for post in range(POSTS_PER_ROBOT):
            answer = disk_api.post("/ttl", json={"ttl_content": payload(index, post), "user": f"robot{index}"})
            assert answer.status_code == 201, answer.text
            body = answer.json()
            # Read the SQLite file directly, right after the answer: the receipt must already be committed.
            with sqlite3.connect(ledger_file) as ledger:
                found = ledger.execute("SELECT COUNT(*) FROM receipts WHERE log_id = ?", (body["log_id"],))
                seen.append((body, found.fetchone()[0] == 1))
        return seen

    with ThreadPoolExecutor(max_workers=ROBOTS) as pool:
        answers = [item for robot_answers in pool.map(robot, range(ROBOTS)) for item in robot_answers]

    sent: set[object] = set()
    for index in range(ROBOTS):
        for post in range(POSTS_PER_ROBOT):
            sent.update(parse(payload(index, post).encode(), RdfFormat.TURTLE))
    exported = disk_api.get("/events", headers={"Accept": "application/n-triples"})
    stored = {line for line in exported.text.splitlines() if line.strip()}

    assert all(receipted for _, receipted in answers)
    assert len(answers) == ROBOTS * POSTS_PER_ROBOT
    assert sum(body["triples_new"] for body, _ in answers) == len(sent) == len(stored)
    verified = disk_api.get("/ledger/verify").json()
    assert verified == {"valid": True, "receipts": ROBOTS * POSTS_PER_ROBOT}
