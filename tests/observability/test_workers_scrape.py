"""`segb serve --workers 2` on a real Virtuoso: whichever worker answers a scrape, /metrics counts the posts every
worker took."""

from __future__ import annotations

import tempfile
from pathlib import Path

import httpx
import pytest

from tests.deploy.test_workers import Workers
from tests.faults.test_crashes import post_turtle
from tests.observability.exposition import samples, value
from tests.support.virtuoso import VirtuosoProcess

pytestmark = pytest.mark.virtuoso

POSTS = 20


def metric_folders() -> set[Path]:
    return set(Path(tempfile.gettempdir()).glob("segb-metrics-*"))


def test_every_scrape_sums_the_posts_of_all_workers(virtuoso: VirtuosoProcess, tmp_path: Path) -> None:
    before = metric_folders()
    workers = Workers(virtuoso, tmp_path / "data", 2)
    assert len(metric_folders() - before) == 1
    try:
        for post in range(POSTS):
            with httpx.Client(base_url=workers.url, timeout=30) as fresh:  # a connection each: spread over workers
                answer = fresh.post("/ttl", json={"ttl_content": post_turtle(1, post), "user": "robot1"})
                assert answer.status_code == 201, answer.text
        for _ in range(6):
            with httpx.Client(base_url=workers.url, timeout=30) as fresh:
                scraped = fresh.get("/metrics")
            assert scraped.status_code == 200, scraped.text
            found = samples(scraped.text)
            assert value(found, "segb_posts_total", outcome="accepted", reason="") == POSTS
            assert value(found, "segb_triples_total", outcome="new") == POSTS * 5
    finally:
        log = workers.stop()
    assert metric_folders() <= before, log[-3000:]  # removed once the workers are gone
