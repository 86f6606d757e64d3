"""The emotion-mirror robot publishing only what is new (`--publish new`): the server ends up with the very graph
the robot holds, each post sending only the triples added since the last."""

from __future__ import annotations

import httpx
import pytest
from pyoxigraph import RdfFormat
from semantic_log_generator import SEGBPublisher

from segb_server.examples.emotion_mirror import run
from segb_server.examples.emotion_mirror.publishing import NewOnly
from tests.support.graphs import value_triples
from tests.support.live_server import LiveServer
from tests.support.net import free_port
from tests.support.robot_posts import mission, run_exchange


def stored(server: LiveServer) -> set[tuple[str, str, object]]:
    answer = httpx.get(f"{server.url}/events", headers={"Accept": "application/n-triples"}, timeout=30)
    assert answer.status_code == 200
    return value_triples(answer.content)


def test_publishing_only_what_is_new_stores_the_robots_whole_graph(live_api: LiveServer) -> None:
    robot = mission("mirror")
    new_only = NewOnly(SEGBPublisher(base_url=live_api.url))
    answers = [new_only.publish(robot.logger)]
    for index in range(5):
        run_exchange(robot, index)
        answers.append(new_only.publish(robot.logger))

    assert all(answer["triples_new"] == answer["triples_received"] > 0 for answer in answers)
    assert sum(answer["triples_received"] for answer in answers) == len(robot.logger.graph)
    assert stored(live_api) == value_triples(robot.logger.serialize().encode(), RdfFormat.TURTLE)


def test_nothing_new_is_not_sent(live_api: LiveServer) -> None:
    robot = mission("mirror")
    new_only = NewOnly(SEGBPublisher(base_url=live_api.url))
    new_only.publish(robot.logger)

    again = new_only.publish(robot.logger)

    assert again["triples_received"] == again["triples_new"] == 0
    ledger = httpx.get(f"{live_api.url}/ledger", timeout=30).json()
    assert [receipt["action"] for receipt in ledger["receipts"]] == ["ingest"]


def test_the_runner_publishes_only_what_is_new_when_asked(
    live_api: LiveServer, capsys: pytest.CaptureFixture[str]
) -> None:
    no_ollama = f"http://127.0.0.1:{free_port()}"
    status = run.main(["--server", live_api.url, "--ollama-host", no_ollama, "--publish", "new"])

    lines = capsys.readouterr().out.strip().splitlines()
    assert status == 0
    sent = [tuple(map(int, line.rsplit("-> ", 1)[1].split()[0:4:3])) for line in lines]
    assert len(sent) > 3
    assert all(new == received for new, received in sent)  # each post held only what was new
