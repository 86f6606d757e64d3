"""A post's answer waits while the reports are too far behind (VIEWS_MAX_LAG_SECONDS), so robots, which wait for
each answer, post at the pace the views keep; never longer than VIEWS_MAX_HOLD_SECONDS, and never refused.

The views are made to fall behind for real: another connection holds the reports' database locked, so the
views' keeper waits for it as it would for a slow view."""

from __future__ import annotations

import asyncio
import sqlite3
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.services.views.pace import ViewsPace
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.settle import kept_rows, settle

REPORTS_FILE = "reports.sqlite3"


def post(url: str, n: int) -> tuple[int, float]:
    """POST one triple; its status and when it was answered (time.monotonic())."""
    turtle = f"<https://example.org/s{n}> <https://example.org/p> {n} ."
    answer = httpx.post(f"{url}/ttl", json={"ttl_content": turtle, "user": "robot"}, timeout=60)
    return answer.status_code, time.monotonic()


@contextmanager
def reports_locked(data_dir: Path) -> Iterator[None]:
    """The reports' database held in a write transaction of another connection until the block ends."""
    connection = sqlite3.connect(data_dir / REPORTS_FILE, isolation_level=None, timeout=30)
    try:
        connection.execute("BEGIN IMMEDIATE")
        yield
        connection.execute("ROLLBACK")
    finally:
        connection.close()


def served(data_dir: Path, max_lag: float, max_hold: float) -> LiveServer:
    settings = make_settings(
        store="oxigraph", data_dir=data_dir, views_max_lag_seconds=max_lag, views_max_hold_seconds=max_hold
    )
    return LiveServer(create_app(settings))


def ready_and_current(url: str) -> None:
    assert post(url, 0)[0] == 201
    kept_rows(url, "conversations")
    settle(url)


def test_while_the_reports_are_too_far_behind_an_answer_waits_for_them(tmp_path: Path) -> None:
    with served(tmp_path, max_lag=0.5, max_hold=30) as server:
        ready_and_current(server.url)
        answered: list[tuple[int, float]] = []
        with reports_locked(tmp_path):
            began = time.monotonic()
            status, at = post(server.url, 1)  # the views are current: answered at once
            assert status == 201 and at - began < 5
            time.sleep(1.0)  # the views now miss an entry that has waited longer than the bound
            robots = [threading.Thread(target=lambda n=n: answered.append(post(server.url, n))) for n in (2, 3, 4)]
            for robot in robots:  # several robots waiting at once, sharing the server's looks at the views
                robot.start()
            time.sleep(1.5)
            assert not answered, "answered while the reports were further behind than VIEWS_MAX_LAG_SECONDS"
            released = time.monotonic()
        for robot in robots:
            robot.join(timeout=30)
        assert [status for status, _ in answered] == [201] * 3
        assert min(at for _, at in answered) >= released  # answered once the views caught up, not before
        settle(server.url)
        count = server.client.post(
            "/sparql", data={"query": "SELECT (COUNT(*) AS ?n) WHERE { ?s <https://example.org/p> ?o }"},
            headers={"Accept": "application/sparql-results+json"},
        ).json()["results"]["bindings"][0]["n"]["value"]  # fmt: skip
        assert int(count) == 5  # every post kept


def answer_seconds_while_behind(data_dir: Path, max_lag: float, max_hold: float) -> float:
    """With the reports stalled and a post they miss a second old: how long the next post took to be answered
    (a 201 either way)."""
    with served(data_dir, max_lag, max_hold) as server:
        ready_and_current(server.url)
        with reports_locked(data_dir):
            assert post(server.url, 1)[0] == 201
            time.sleep(1.0)
            began = time.monotonic()
            status, at = post(server.url, 2)
            assert status == 201
            return at - began


def test_an_answer_waits_no_longer_than_the_longest_hold(tmp_path: Path) -> None:
    assert 1.0 <= answer_seconds_while_behind(tmp_path, max_lag=0.2, max_hold=1.0) < 5  # still stalled: answered


def test_with_no_bound_an_answer_never_waits_for_the_reports(tmp_path: Path) -> None:
    assert answer_seconds_while_behind(tmp_path, max_lag=0, max_hold=30) < 1.0


class Progress:
    """The views' progress as the pace reads it: far behind, and possibly failing or being built in full."""

    def __init__(self, *, failing: bool = False, building_all: bool = False) -> None:
        self.failing, self.building = failing, building_all

    def views_behind(self) -> int:
        return 50

    def views_lag_seconds(self) -> float:
        return 60.0

    def views_failing(self) -> bool:
        return self.failing

    def views_building_all(self) -> bool:
        return self.building


@pytest.mark.parametrize(
    ("progress", "holds"),
    [(Progress(), True), (Progress(failing=True), False), (Progress(building_all=True), False)],
    ids=["behind", "failing", "built-again-from-the-store"],
)
def test_an_answer_waits_only_while_waiting_lets_the_views_catch_up(progress: Progress, holds: bool) -> None:
    """A minute behind: a post waits for the views' upkeep, but not for a keeper retrying an outage, nor while
    every view is built again from the store (after an erasure: minutes on a big store, which posts do not slow)."""
    pace = ViewsPace(progress, max_lag_seconds=1.0, max_hold_seconds=0.5)
    with ThreadPoolExecutor(1) as loop_thread:  # a loop of its own, whatever this thread runs (a browser's)
        waited = loop_thread.submit(asyncio.run, pace.hold()).result()
    assert (waited >= 0.5) is holds, waited
