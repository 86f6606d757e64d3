"""Two "hosts" sharing one store (a real Virtuoso) and one state database (a real PostgreSQL), as API servers on
several machines do: each has a data directory of its own, and nothing else in common.

Robots post to both; afterwards the journal is one valid chain with one receipt per post, every acknowledged
triple is stored, each host's reports show every post (each host keeps its own views, from the shared
journal), resolutions on both hosts agree, and when the applying host dies the other one takes over."""

from __future__ import annotations

import os
import signal
import uuid
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from tests.deploy.test_workers import EX, Workers, applier_pid, post_json, post_message
from tests.faults.test_crashes import all_receipts, caught_up, check_consistent, post_turtle
from tests.support.virtuoso import VirtuosoProcess

pytestmark = [pytest.mark.virtuoso, pytest.mark.postgres]

ROBOTS = 8
POSTS_PER_ROBOT = 40


@pytest.fixture
def hosts(virtuoso: VirtuosoProcess, postgres_url: str, tmp_path: Path) -> Iterator[list[Workers]]:
    graph = f"http://amor-segb/test/{uuid.uuid4().hex}"
    started = [
        Workers(virtuoso, tmp_path / f"host-{name}", workers, graph_uri=graph, state_url=postgres_url)
        for name, workers in (("a", 2), ("b", 1))
    ]
    yield started
    for host in started:
        host.stop()


def test_hosts_sharing_the_state_make_one_chain_and_each_shows_every_post(hosts: list[Workers]) -> None:
    acknowledged: dict[str, str] = {}

    def robot(number: int) -> None:
        for post in range(POSTS_PER_ROBOT):
            turtle = post_turtle(number, post)
            host = hosts[(number + post) % len(hosts)]  # every robot's posts alternate between the hosts
            status, answer = post_json(host.url, "/ttl", {"ttl_content": turtle, "user": f"robot{number}"})
            assert status == 201, answer
            acknowledged[str(answer["log_id"])] = turtle

    with ThreadPoolExecutor(ROBOTS) as pool:
        list(pool.map(robot, range(ROBOTS)))
    messages = [f"{EX}message/hosts-{call}" for call in range(8)]
    statuses = [post_message(hosts[call % 2].url, message, 0) for call, message in enumerate(messages)]
    assert statuses == [201] * len(messages)

    for host in hosts:
        caught_up(host.url)
        check_consistent(host.url, acknowledged)
    receipts = list(all_receipts(hosts[1].url))
    assert sorted(receipt["sequence"] for receipt in receipts) == list(range(1, len(receipts) + 1))
    assert set(acknowledged) <= {receipt["log_id"] for receipt in receipts}
    assert len(receipts) == len(acknowledged) + len(messages)
    for host in hosts:  # each host's own views, kept from the shared journal
        rows = httpx.get(f"{host.url}/reports/conversations", params={"limit": 1000}, timeout=30).json()["rows"]
        assert set(messages) <= {str(row["message"]) for row in rows}, host.url


def test_resolutions_on_both_hosts_give_one_context(hosts: list[Workers]) -> None:
    body = {
        "event_kind": "human_utterance",
        "observed_at": "2026-05-04T10:00:00+00:00",
        "subject_uri": "https://example.org/people/maria",
        "modality": "speech",
        "text": "Good morning, robot!",
    }

    def resolve(call: int) -> str:
        status, answer = post_json(hosts[call % 2].url, "/shared-context/resolve", body)
        assert status == 200, answer
        return str(answer["shared_context_uri"])

    with ThreadPoolExecutor(16) as pool:
        assert len(set(pool.map(resolve, range(16)))) == 1


def test_when_the_applying_host_dies_the_other_applies(hosts: list[Workers], postgres_url: str) -> None:
    first = post_turtle(1, 0)
    status, answer = post_json(hosts[0].url, "/ttl", {"ttl_content": first, "user": "robot1"})
    assert status == 201, answer
    caught_up(hosts[0].url)
    applier = applier_pid(postgres_url)
    assert os.getpgid(applier) == hosts[0].process.pid, "host a started first: one of its processes applies"
    os.killpg(hosts[0].process.pid, signal.SIGKILL)
    hosts[0].process.wait()
    late = post_turtle(2, 0)
    status, late_answer = post_json(hosts[1].url, "/ttl", {"ttl_content": late, "user": "robot2"})
    assert status == 201, late_answer
    caught_up(hosts[1].url, timeout=30)
    check_consistent(hosts[1].url, {str(answer["log_id"]): first, str(late_answer["log_id"]): late})
    rows = httpx.get(f"{hosts[1].url}/ledger", params={"limit": 10}, timeout=30).json()["receipts"]
    assert rows[0]["log_id"] == late_answer["log_id"]
