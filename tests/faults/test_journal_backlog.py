"""The journal's backlog quota (JOURNAL_MAX_BACKLOG) counts what the store really has to catch up: a restart
on a long journal, or a store that goes away, must not make every entry ever written look unapplied (a month
of posts is far more than the quota, and robots would get 503s for nothing)."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from tests.api.test_health import wait_until_ready
from tests.conftest import make_settings, virtuoso_store
from tests.support.live_server import LiveServer
from tests.support.settle import settle
from tests.support.virtuoso import VirtuosoProcess


def post(url: str, n: int) -> httpx.Response:
    turtle = f"<https://example.org/s{n}> <https://example.org/p> {n} ."
    return httpx.post(f"{url}/ttl", json={"ttl_content": turtle, "user": "robot"}, timeout=30)


def test_a_restart_on_a_journal_longer_than_the_quota_answers_caught_up_at_once(tmp_path: Path) -> None:
    settings = make_settings(store="oxigraph", data_dir=tmp_path, journal_max_backlog=3)
    with LiveServer(create_app(settings)) as server:
        assert [post(server.url, n).status_code for n in range(10)] == [201] * 10
        settle(server.url)
    with LiveServer(create_app(settings)) as server:  # the first answers, before the applier's first look
        ready = httpx.get(f"{server.url}/healthz/ready", timeout=30)
        posted = post(server.url, 10)
    assert (ready.status_code, ready.text) == (200, '{"ready": true, "oxigraph": true}')
    assert posted.status_code == 201, posted.text


@pytest.mark.virtuoso
def test_while_virtuoso_is_away_posts_are_kept_up_to_the_quota_then_refused_with_retry_after(tmp_path: Path) -> None:
    (tmp_path / "virtuoso").mkdir()
    virtuoso = VirtuosoProcess(tmp_path / "virtuoso")
    virtuoso.start()
    store = virtuoso_store(virtuoso, "http://amor-segb/events")
    settings = make_settings(store="virtuoso", ingest_ack="journal", data_dir=tmp_path / "data", journal_max_backlog=3)
    try:
        with LiveServer(create_app(settings, store=store)) as server:
            assert [post(server.url, n).status_code for n in range(10)] == [201] * 10
            settle(server.url)
            virtuoso.stop()
            kept = [post(server.url, n) for n in range(10, 14)]
            assert [answer.status_code for answer in kept[:3]] == [201] * 3, kept[-1].text  # up to the quota
            refused = post(server.url, 14)
            assert refused.status_code == 503 and refused.headers["retry-after"]
            assert "JOURNAL_MAX_BACKLOG" in refused.json()["detail"]

            virtuoso.start()
            assert wait_until_ready(server.url).status_code == 200
            assert post(server.url, 15).status_code == 201  # accepted again once the backlog is applied
            settle(server.url)
            assert store.count() == 10 + len([a for a in kept if a.status_code == 201]) + 1
    finally:
        store.close()
        virtuoso.stop()
