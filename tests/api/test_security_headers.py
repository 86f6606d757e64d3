"""What every API answer carries: security headers, and for an error nobody foresaw, a 500 in the one error
shape with its request id, CORS headers for allowed origins, and a closed connection."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest
from fastapi import FastAPI

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store
from tests.conftest import make_settings
from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer

ORIGIN = "https://auditors.example.org"


@pytest.fixture
def failing_api(memory_store: Store) -> Iterator[LiveServer]:
    """The API with one more route whose handler fails the way an unforeseen bug would, over real HTTP (the
    answer closes the connection)."""
    app: FastAPI = create_app(make_settings(cors_origins=ORIGIN), store=memory_store)

    async def broken() -> None:
        raise RuntimeError("an unforeseen failure with internal details")

    app.add_api_route("/broken", broken)
    with LiveServer(app) as server:
        yield server


def test_json_answers_carry_the_security_headers(memory_api: InProcess) -> None:
    answer = memory_api.get("/healthz/ready")
    assert answer.headers["x-content-type-options"] == "nosniff"
    assert answer.headers["referrer-policy"] == "no-referrer"
    assert answer.headers["content-security-policy"].startswith("default-src 'none'")
    docs = memory_api.get("/docs")
    assert "script-src 'self'" in docs.headers["content-security-policy"]  # its own policy, not the JSON one


def test_an_unforeseen_error_is_a_clean_500_with_id_and_cors(failing_api: LiveServer) -> None:
    with httpx.Client(base_url=failing_api.url) as client:
        answer = client.get("/broken", headers={"Origin": ORIGIN, "X-Request-ID": "trace-42"})
        assert answer.status_code == 500
        assert answer.json() == {
            "detail": "Internal server error; see the server log.",
            "error": "internal_error",
            "status": 500,
        }
        assert "internal details" not in answer.text
        assert answer.headers["x-request-id"] == "trace-42"
        assert answer.headers["access-control-allow-origin"] == ORIGIN
        assert answer.headers["connection"] == "close"
        assert client.get("/healthz/live").status_code == 200  # the client reconnects; the server is fine
