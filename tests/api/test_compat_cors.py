"""CORS, through the whole app served in process: every answer to an allowed origin carries the CORS headers,
errors included (4xx, a 503 with the store down, a 502 from a store that answers nonsense), preflights, and the
credentials setting.

A browser hides from scripts every answer without `Access-Control-Allow-Origin`, errors too, so a web UI on
another origin would see a network failure instead of the error's JSON. The reference answered its 500s
without CORS headers."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from segb_server.backend.store.base import Store
from segb_server.backend.store.sparql_http import SparqlHttpStore
from tests.api.test_compat_validate import unreachable_store
from tests.conftest import make_settings
from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
ORIGIN = "https://audit.example"
OTHER_ORIGIN = "https://evil.example"
TURTLE = "<https://example.org/a> a <https://example.org/B> .\n<https://example.org/b> a <https://example.org/B> ."


def bearer(*roles: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {mint_token(SECRET, username='t', roles=roles).token}"}


def cors_app(store: Store, **settings: object) -> LiveServer:
    values: dict[str, object] = {"cors_origins": f"{ORIGIN}, https://ui.example", "secret_key": SECRET, **settings}
    return InProcess(create_app(make_settings(**values), store=store))


@pytest.fixture
def server(memory_store: Store) -> Iterator[InProcess]:
    with cors_app(memory_store, max_body_bytes=2048, sparql_max_rows=1) as live:
        live.post("/ttl", content=TURTLE, headers={"Content-Type": "text/turtle", **bearer("logger")})
        yield live


def assert_cors(answer: httpx.Response, origin: str = ORIGIN) -> None:
    assert answer.headers.get("access-control-allow-origin") == origin, (answer.status_code, answer.headers)
    assert "origin" in answer.headers.get("vary", "").lower()
    exposed = {name.strip().lower() for name in answer.headers["access-control-expose-headers"].split(",")}
    assert {"x-request-id", "x-segb-truncated", "x-segb-max-rows", "retry-after"} <= exposed
    assert answer.headers["x-request-id"]
    assert "access-control-allow-credentials" not in answer.headers  # off unless CORS_ALLOW_CREDENTIALS


# (method, path, request) → the status the API answers
ANSWERS: dict[str, tuple[str, str, dict[str, object], int]] = {
    "ok": ("GET", "/healthz/live", {}, 200),
    "400 bad query": ("GET", "/sparql", {"params": {"query": "SELECT ?s {"}, "headers": bearer("auditor")}, 400),
    "401 no token": ("GET", "/events", {}, 401),
    "403 wrong role": ("GET", "/logs/server", {"headers": bearer("auditor")}, 403),
    "404 unknown report": ("GET", "/reports/nope", {"headers": bearer("auditor")}, 404),
    "405 wrong method": ("DELETE", "/events", {"headers": bearer("auditor")}, 405),
    "406 not acceptable": (
        "GET",
        "/sparql",
        {"params": {"query": "ASK {}"}, "headers": {"Accept": "text/html", **bearer("auditor")}},
        406,
    ),
    "413 too large": (
        "POST",
        "/ttl",
        {"content": "#" * 4096, "headers": {"Content-Type": "text/turtle", **bearer("logger")}},
        413,
    ),
    "415 wrong type": (
        "POST",
        "/ttl",
        {"content": TURTLE, "headers": {"Content-Type": "text/html", **bearer("logger")}},
        415,
    ),
    "422 bad parameter": ("GET", "/logs/server", {"params": {"limit": 0}, "headers": bearer("admin")}, 422),
}


@pytest.mark.parametrize("name", sorted(ANSWERS))
def test_every_answer_to_an_allowed_origin_carries_cors_errors_included(server: InProcess, name: str) -> None:
    method, path, request, status = ANSWERS[name]
    headers = {"Origin": ORIGIN, **request.get("headers", {})}
    answer = server.client.request(method, path, **{**request, "headers": headers})
    assert answer.status_code == status, answer.text
    assert_cors(answer)
    if status >= 400:
        assert answer.json()["status"] == status  # the error's JSON, readable by the page's script


def test_a_truncated_answer_exposes_its_flag_to_scripts(server: InProcess) -> None:
    answer = server.get(
        "/sparql",
        params={"query": "SELECT * { ?s ?p ?o }"},
        headers={"Origin": ORIGIN, **bearer("auditor")},
    )
    assert (answer.status_code, answer.headers["x-segb-truncated"], answer.headers["x-segb-max-rows"]) == (
        200,
        "true",
        "1",
    )
    assert_cors(answer)


def test_another_origin_gets_no_cors_headers_even_on_errors(server: InProcess) -> None:
    for path in ("/healthz/live", "/events", "/reports/nope"):
        answer = server.get(path, headers={"Origin": OTHER_ORIGIN})
        assert "access-control-allow-origin" not in answer.headers, path
    assert "access-control-allow-origin" not in server.get("/healthz/live").headers  # no Origin


def test_a_second_listed_origin_is_allowed_too(server: InProcess) -> None:
    assert_cors(server.get("/healthz/live", headers={"Origin": "https://ui.example"}), "https://ui.example")


def test_server_errors_carry_cors_with_the_store_down() -> None:
    store = unreachable_store()
    try:
        with cors_app(store) as server:
            origin = {"Origin": ORIGIN}
            ready = server.get("/healthz/ready", headers=origin)
            query = server.get("/sparql", params={"query": "ASK {}"}, headers={**origin, **bearer("auditor")})
            publish = server.post(
                "/ttl",
                content=TURTLE,
                headers={**origin, "Content-Type": "text/turtle", **bearer("logger")},
            )
    finally:
        store.close()
    for answer in (ready, query, publish):
        assert answer.status_code == 503, answer.text
        assert_cors(answer)
    assert (query.json()["error"], publish.json()["error"]) == ("store_unavailable", "store_unavailable")


def test_server_errors_carry_cors_when_the_store_answers_nonsense(live_api: LiveServer) -> None:
    # An HTTP server that is no SPARQL endpoint: it answers queries with a 405, which the API reports as a 502.
    endpoint = f"{live_api.url}/healthz/live"
    store = SparqlHttpStore(query_endpoint=endpoint, update_endpoint=endpoint, graph_uri="http://amor-segb/events")
    try:
        with cors_app(store) as server:
            answer = server.get(
                "/resource",
                params={"iri": "https://example.org/a"},
                headers={"Origin": ORIGIN, **bearer("auditor")},
            )
    finally:
        store.close()
    assert (answer.status_code, answer.json()["error"]) == (502, "store_error")
    assert_cors(answer)


PREFLIGHT = {
    "Origin": ORIGIN,
    "Access-Control-Request-Method": "POST",
    "Access-Control-Request-Headers": "authorization, content-type, content-encoding, x-request-id",
}


def test_a_preflight_allows_what_the_api_uses_and_needs_no_token(server: InProcess) -> None:
    answer = server.client.options("/ttl", headers=PREFLIGHT)
    assert answer.status_code == 200, answer.text
    assert answer.headers["access-control-allow-origin"] == ORIGIN
    methods = {method.strip() for method in answer.headers["access-control-allow-methods"].split(",")}
    assert {"GET", "POST"} <= methods
    allowed = {name.strip().lower() for name in answer.headers["access-control-allow-headers"].split(",")}
    assert {"authorization", "content-type", "content-encoding", "x-request-id"} <= allowed
    assert "access-control-allow-credentials" not in answer.headers


@pytest.mark.parametrize(
    "change",
    [{"Origin": OTHER_ORIGIN}, {"Access-Control-Request-Method": "PUT"}, {"Access-Control-Request-Headers": "x-other"}],
    ids=["other origin", "other method", "other header"],
)
def test_a_preflight_refuses_what_is_not_allowed(server: InProcess, change: dict[str, str]) -> None:
    answer = server.client.options("/ttl", headers={**PREFLIGHT, **change})
    assert answer.status_code == 400
    if "Origin" in change:
        assert "access-control-allow-origin" not in answer.headers


def test_credentials_are_allowed_only_when_configured(memory_store: Store) -> None:
    with cors_app(memory_store, cors_allow_credentials=True) as server:
        preflight = server.client.options("/events", headers={**PREFLIGHT, "Access-Control-Request-Method": "GET"})
        refused = server.get("/events", headers={"Origin": ORIGIN})
    for answer in (preflight, refused):
        assert answer.headers["access-control-allow-credentials"] == "true"
        assert answer.headers["access-control-allow-origin"] == ORIGIN  # never "*" with credentials
    assert refused.status_code == 401
