"""GET /metrics through the app served in process: posts accepted and refused by reason, triples, latency,
lag, findings by rule, the store's health, erasures and bundles; who may scrape it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from segb_server.backend.store.base import StoreUnavailable
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from tests.conftest import make_settings
from tests.observability.exposition import Samples, samples, value
from tests.support.in_process import InProcess, publisher_for
from tests.support.scenarios import at
from tests.support.settle import settle

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
SCRAPER = "a-scraper-token-that-is-long-enough-too"
ROBOT = "https://example.org/segb/robots/ari/v1/robot_ari"
TURTLE = {"content-type": "text/turtle"}


@pytest.fixture
def api() -> Iterator[InProcess]:
    with InProcess(create_app(make_settings())) as served:
        yield served


def scrape(api: InProcess, **options: object) -> Samples:
    answer = api.get("/metrics", **options)  # type: ignore[arg-type]
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"].startswith("text/plain; version=0.0.4")
    return samples(answer.text)


def test_posts_are_counted_by_outcome_and_reason_with_their_triples(api: InProcess) -> None:
    before = scrape(api)
    turtle = f"<{ROBOT}> a <http://kb.openrobots.org#Robot> ; <http://schema.org/name> 'ARI' ."
    assert api.post("/ttl", json={"ttl_content": turtle, "user": "ari"}).status_code == 201
    assert api.post("/ttl", json={"ttl_content": turtle, "user": "ari"}).status_code == 201  # known already
    assert api.post("/ttl", json={"ttl_content": "<a> <b", "user": "ari"}).status_code == 400
    after = scrape(api)

    def grew(name: str, **labels: str) -> float:
        return value(after, name, **labels) - value(before, name, **labels)

    assert grew("segb_posts_total", outcome="accepted", reason="") == 2
    assert grew("segb_posts_total", outcome="refused", reason="invalid_rdf") == 1
    assert grew("segb_triples_total", outcome="new") == 2
    assert grew("segb_triples_total", outcome="known") == 2
    assert grew("segb_ingest_seconds_count", outcome="accepted") == 2
    assert grew("segb_ingest_seconds_bucket", outcome="refused", le="+Inf") == 1


def test_lag_health_and_findings_are_read_at_scrape_time(api: InProcess) -> None:
    publisher = publisher_for(api.client, "mirror")
    mission = EmotionMirrorMission.start(
        RobotConfig(), human_id="maria", human_name="Maria", publish=lambda logger: logger.publish(publisher)
    )
    mission.on_user_utterance("Are you there?", at(0))
    settle(api.client)
    found = scrape(api)
    assert value(found, "segb_findings", rule="unanswered-message", severity="warning") == 1
    assert value(found, "segb_store_up", store="memory") == 1
    assert value(found, "segb_journal_up") == 1
    assert ("segb_lag_entries", (("stage", "apply"),)) in found
    assert value(found, "segb_lag_seconds", stage="views") >= 0
    text = api.get("/metrics").text
    assert "# TYPE segb_view_lag_entries gauge" in text and "# TYPE segb_view_lag_seconds gauge" in text


def test_erasures_and_evidence_bundles_are_counted(api: InProcess) -> None:
    zoe = "https://example.org/h/zoe"
    posted = api.post("/ttl", content=f"<{zoe}> a <http://xmlns.com/foaf/0.1/Person> .", headers=TURTLE)
    assert posted.status_code == 201, posted.text
    before = scrape(api)
    erased = api.post("/humans/erase", json={"iri": zoe, "reason": "request 1"})
    assert erased.status_code < 300, erased.text
    assert api.get("/evidence").status_code == 200
    settle(api.client)
    after = scrape(api)
    assert value(after, "segb_erasures_total") - value(before, "segb_erasures_total") == 1
    assert value(after, "segb_evidence_bundles_served_total") - value(before, "segb_evidence_bundles_served_total") == 1


@pytest.fixture(scope="module")
def guarded() -> Iterator[InProcess]:
    with InProcess(create_app(make_settings(secret_key=SECRET, metrics_token=SCRAPER))) as served:
        yield served


def test_the_scraper_token_lets_a_scrape_in_and_nothing_else(guarded: InProcess) -> None:
    assert guarded.get("/metrics", headers={"Authorization": f"Bearer {SCRAPER}"}).status_code == 200
    assert guarded.get("/reports", headers={"Authorization": f"Bearer {SCRAPER}"}).status_code == 401
    assert guarded.get("/metrics", headers={"Authorization": f"Bearer {SCRAPER}x"}).status_code == 401
    assert guarded.get("/metrics").status_code == 401


def test_an_auditor_may_scrape_and_a_logger_may_not(guarded: InProcess) -> None:
    def bearer(role: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {mint_token(SECRET, username='t', roles=[role]).token}"}

    assert guarded.get("/metrics", headers=bearer("auditor")).status_code == 200
    assert guarded.get("/metrics", headers=bearer("logger")).status_code == 403


def test_a_short_scraper_token_is_refused_at_start() -> None:
    with pytest.raises(ValueError, match="METRICS_TOKEN must be at least 32"):
        make_settings(metrics_token="short")


class PingFailing(OxigraphStore):
    """The embedded store, not answering pings once `down`."""

    down = False

    def ping(self) -> None:
        if self.down:
            raise StoreUnavailable("the store did not answer the ping")
        super().ping()


def test_a_store_that_does_not_answer_is_a_zero_not_a_failed_scrape(tmp_path: Path) -> None:
    store = PingFailing("http://amor-segb/events", tmp_path / "store")
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path / "data"), store=store)) as api:
        assert value(scrape(api), "segb_store_up", store="oxigraph") == 1
        store.down = True
        assert value(scrape(api), "segb_store_up", store="oxigraph") == 0
    store.close()
