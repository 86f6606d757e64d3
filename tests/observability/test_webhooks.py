"""Webhooks for findings: a local receiver checks every signature, is retried after refusing, and hears of a
finding when it appears and again when it is resolved; an unreachable URL never slows or fails a post."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.services.observability.deliveries import Deliveries
from segb_server.backend.services.observability.metrics import WEBHOOK_DELIVERIES
from segb_server.backend.services.observability.signing import signature, verified
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from tests.conftest import make_settings
from tests.observability.receiver import Receiver
from tests.support.in_process import InProcess, publisher_for
from tests.support.net import free_port
from tests.support.scenarios import at
from tests.support.settle import settle

SECRET = "a-webhook-secret-long-enough-to-sign-with"


def mirror(api: InProcess) -> EmotionMirrorMission:
    publisher = publisher_for(api.client, "mirror")
    return EmotionMirrorMission.start(
        RobotConfig(), human_id="maria", human_name="Maria", publish=lambda logger: logger.publish(publisher)
    )


@pytest.fixture
def receiver() -> Iterator[Receiver]:
    with Receiver(SECRET, refuse_first=1) as listening:
        yield listening


def test_a_new_finding_and_its_resolution_are_delivered_signed_after_a_refusal(receiver: Receiver) -> None:
    settings = make_settings(webhook_urls=receiver.url, webhook_secret=SECRET, webhook_min_severity="warning")
    with InProcess(create_app(settings)) as api:
        mission = mirror(api)
        time.sleep(1.5)  # the first look at the findings: what is there before is the starting point
        exchange = mission.on_user_utterance("Are you there?", at(0))
        settle(api.client)
        (new,) = receiver.wait_for(1)
        assert receiver.attempts[:2] == [new["delivery"], new["delivery"]]  # refused once with a 500, then again
        assert new["event"] == new["event_header"] == "finding.new"
        assert (new["rule"], new["severity"], new["focus"]) == ("unanswered-message", "warning", str(exchange.heard))
        assert str(new["human"]).endswith("/human_maria")  # her pseudonymous IRI, as the log gives it
        assert "Maria" in str(new["message"])  # the rule's own message, as /findings shows it
        assert str(new["explain"]).endswith(
            "/explain?iri=" + str(exchange.heard).replace(":", "%3A").replace("/", "%2F")
        )
        mission.respond(exchange, at(1.5))
        settle(api.client)
        resolved = receiver.wait_for(2)[1]
        assert (resolved["event"], resolved["focus"]) == ("finding.resolved", str(exchange.heard))
        assert receiver.bad_signatures == 0
        listed = api.get("/webhooks/deliveries").json()
        assert [delivery["event"] for delivery in listed] == ["finding.resolved", "finding.new"]
        assert listed[1]["outcomes"] == {receiver.url: "delivered"}
        again = api.post(f"/webhooks/deliveries/{new['delivery']}/redeliver")
        assert again.status_code == 202, again.text
        assert receiver.wait_for(3)[2]["delivery"] == new["delivery"]
        assert api.post("/webhooks/deliveries/nope/redeliver").status_code == 404


def test_an_unreachable_webhook_never_slows_or_fails_a_post() -> None:
    nowhere = f"http://127.0.0.1:{free_port()}/hook"  # nothing listens there
    settings = make_settings(webhook_urls=nowhere, webhook_secret=SECRET, webhook_min_severity="info")
    with InProcess(create_app(settings)) as api:
        mission = mirror(api)
        started = time.monotonic()
        for turn in range(5):
            mission.on_user_utterance(f"Hello {turn}?", at(10 * turn))  # each an unanswered message
        settle(api.client)
        assert time.monotonic() - started < 10
        assert api.get("/healthz/ready").status_code == 200


def test_a_full_queue_drops_and_counts_deliveries_without_waiting() -> None:
    deliveries = Deliveries([f"http://127.0.0.1:{free_port()}/hook"], SECRET, queue_size=1)  # not started: stays full
    dropped = WEBHOOK_DELIVERIES.labels("dropped")._value.get()
    started = time.monotonic()
    for index in range(50):
        deliveries.send("finding.new", {"rule": "r", "index": index})
    assert time.monotonic() - started < 1
    assert WEBHOOK_DELIVERIES.labels("dropped")._value.get() - dropped == 49


def test_a_signature_is_refused_when_stale_altered_or_made_with_another_key() -> None:
    body = b'{"event": "finding.new"}'
    header = signature(SECRET, body, timestamp=1_000_000)
    assert verified(SECRET, body, header, now=1_000_100)
    assert not verified(SECRET, body, header, now=1_000_000 + 301)  # a replay after five minutes
    assert not verified(SECRET, body + b" ", header, now=1_000_100)
    assert not verified("another-secret-of-the-same-good-length", body, header, now=1_000_100)
    assert not verified(SECRET, body, "v1=abc", now=1_000_100)


def test_webhooks_need_a_strong_secret_and_http_urls() -> None:
    with pytest.raises(ValueError, match="needs a WEBHOOK_SECRET of at least 32"):
        make_settings(webhook_urls="http://127.0.0.1:9/hook", webhook_secret="short")
    with pytest.raises(ValueError, match="'ftp://x' is not an http"):
        make_settings(webhook_urls="ftp://x", webhook_secret=SECRET)
