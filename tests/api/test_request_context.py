"""Request ids (kept when safe, minted otherwise, echoed and logged) and CORS, through the whole app in process."""

from __future__ import annotations

import logging

import pytest

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.in_process import InProcess


def test_a_safe_request_id_is_echoed(memory_api: InProcess) -> None:
    answer = memory_api.get("/healthz/live", headers={"X-Request-ID": "robot-7.run_42"})
    assert answer.headers["x-request-id"] == "robot-7.run_42"


@pytest.mark.parametrize("hostile", ["two words", "<script>", "x" * 65, "id\tinjected", "ü"])
def test_an_unsafe_request_id_is_replaced(memory_api: InProcess, hostile: str) -> None:
    answer = memory_api.get("/healthz/live", headers={"X-Request-ID": hostile.encode("utf-8")})
    minted = answer.headers["x-request-id"]
    assert minted != hostile and len(minted) == 32 and int(minted, 16) >= 0


def test_every_answer_carries_a_fresh_id_and_the_request_is_logged(
    memory_api: InProcess, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.INFO, logger="segb.requests"):
        first = memory_api.get("/reports/nope")
        second = memory_api.get("/reports/nope")
    assert first.status_code == 404
    assert first.headers["x-request-id"] != second.headers["x-request-id"]
    logged = [r.getMessage() for r in caplog.records if first.headers["x-request-id"] in r.getMessage()]
    assert logged and "path=/reports/nope status=404" in logged[0] and "method=GET" in logged[0]


def test_cors_is_off_by_default(memory_api: InProcess) -> None:
    answer = memory_api.get("/healthz/live", headers={"Origin": "https://evil.example"})
    assert "access-control-allow-origin" not in answer.headers


def test_cors_allows_only_the_configured_origins(memory_store) -> None:  # type: ignore[no-untyped-def]
    app = create_app(make_settings(cors_origins="https://audit.example"), store=memory_store)
    with InProcess(app) as served:
        preflight = {"Access-Control-Request-Method": "GET", "Access-Control-Request-Headers": "authorization"}
        allowed = served.client.options("/reports", headers={"Origin": "https://audit.example", **preflight})
        refused = served.client.options("/reports", headers={"Origin": "https://evil.example", **preflight})
        simple = served.get("/healthz/live", headers={"Origin": "https://audit.example"})
    assert allowed.status_code == 200
    assert allowed.headers["access-control-allow-origin"] == "https://audit.example"
    assert "access-control-allow-origin" not in refused.headers
    assert simple.headers["access-control-allow-origin"] == "https://audit.example"
    assert "x-request-id" in simple.headers["access-control-expose-headers"].lower()
