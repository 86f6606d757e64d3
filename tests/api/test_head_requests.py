"""HEAD is answered wherever GET is (`curl -I /healthz/ready`, uptime monitors): the GET's status and headers, no
body; a stream ends at once instead of running for nobody; a route without GET still says 405. Over real HTTP
(uvicorn)."""

from __future__ import annotations

import httpx

from tests.support.live_server import LiveServer


def test_head_answers_as_get_without_a_body(live_api: LiveServer) -> None:
    got = httpx.get(f"{live_api.url}/healthz/ready")
    head = httpx.head(f"{live_api.url}/healthz/ready")
    assert (head.status_code, head.content) == (got.status_code, b"")
    assert head.headers["content-type"] == got.headers["content-type"] == "application/json"
    assert head.headers["x-request-id"] and head.headers["x-content-type-options"] == "nosniff"
    assert httpx.head(f"{live_api.url}/reports/nowhere").status_code == 404
    assert httpx.head(f"{live_api.url}/ttl").status_code == 405  # POST only


def test_head_on_a_live_stream_ends_at_once(live_api: LiveServer) -> None:
    head = httpx.head(f"{live_api.url}/reports/stream", timeout=5)
    assert head.status_code == 200 and head.headers["content-type"].startswith("text/event-stream")
    assert httpx.get(f"{live_api.url}/healthz/live", timeout=5).status_code == 200  # the server is not held up
