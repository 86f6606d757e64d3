"""Debian's Prometheus scrapes a live server's /metrics with the scraper's token, and the series come back through
its query API after robots post."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from tests.conftest import make_settings
from tests.observability.exposition import samples, value
from tests.observability.prometheus import PrometheusProcess
from tests.support.live_server import LiveServer

pytestmark = pytest.mark.processes

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
SCRAPER = "a-scraper-token-that-is-long-enough-too"
ROBOT = "https://example.org/segb/robots/ari/v1/robot_ari"


@pytest.fixture
def server() -> Iterator[LiveServer]:
    with LiveServer(create_app(make_settings(secret_key=SECRET, metrics_token=SCRAPER))) as live:
        yield live


@pytest.fixture
def prometheus(server: LiveServer) -> Iterator[PrometheusProcess]:
    process = PrometheusProcess(f"127.0.0.1:{server.port}", SCRAPER)
    process.start()
    yield process
    process.stop()


def test_prometheus_reads_back_the_posts_the_server_counted(server: LiveServer, prometheus: PrometheusProcess) -> None:
    logger = {"Authorization": f"Bearer {mint_token(SECRET, username='ari', roles=['logger']).token}"}
    # The counters are the process's: tests run before this one in it have counted too.
    before = samples(server.get("/metrics", headers={"Authorization": f"Bearer {SCRAPER}"}).text)
    accepted, refused = (
        value(before, "segb_posts_total", outcome="accepted", reason=""),
        value(before, "segb_posts_total", outcome="refused", reason="invalid_rdf"),
    )
    new = value(before, "segb_triples_total", outcome="new")
    for index in range(3):
        turtle = f"<{ROBOT}> <http://schema.org/name> 'ARI {index}' ."
        assert server.post("/ttl", json={"ttl_content": turtle, "user": "ari"}, headers=logger).status_code == 201
    assert server.post("/ttl", json={"ttl_content": "<a> <b", "user": "ari"}, headers=logger).status_code == 400

    assert prometheus.value_when('segb_posts_total{job="segb",outcome="accepted"}', accepted + 3) == accepted + 3
    assert prometheus.value_when('segb_posts_total{outcome="refused",reason="invalid_rdf"}', refused + 1) == refused + 1
    assert prometheus.value_when('segb_triples_total{outcome="new"}', new + 3) == new + 3
    assert prometheus.value_when('segb_store_up{store="memory"}', 1) == 1
    assert prometheus.query('histogram_quantile(0.5, sum by (le) (segb_ingest_seconds_bucket{outcome="accepted"}))')
    (target,) = prometheus.targets_up()
    assert target["health"] == "up", target
