"""Every API route against every kind of caller, with authentication on, through the whole app served in process.

The route list comes from the running app's OpenAPI description, so a new route without an entry in
`REQUIRED_ROLE` fails here until someone decides who may call it.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import httpx
import jwt
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from tests.cli.test_demo import REPORTS
from tests.conftest import make_settings
from tests.support.in_process import InProcess, publisher_for

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
PUBLIC = None
ANY_TOKEN = "any"
# (method, path) → the role it needs; PUBLIC needs nothing, ANY_TOKEN any valid token.
REQUIRED_ROLE: dict[tuple[str, str], str | None] = {
    ("GET", "/healthz/live"): PUBLIC,
    ("GET", "/healthz/ready"): PUBLIC,
    ("GET", "/metrics"): "auditor",  # or the bearer of METRICS_TOKEN (tests/observability)
    ("GET", "/auth/mode"): PUBLIC,
    ("GET", "/auth/whoami"): ANY_TOKEN,
    ("POST", "/ttl"): "logger",
    ("POST", "/ttl/validate"): "admin",  # the reference's role: its insert page is the admins'
    ("POST", "/ttl/delete_all"): "admin",
    ("GET", "/events"): "auditor",
    ("GET", "/vocabulary"): PUBLIC,
    ("GET", "/reports"): "auditor",
    **{("GET", f"/reports/{name}"): "auditor" for name in REPORTS},
    ("GET", "/reports/stream"): "auditor",
    ("GET", "/timeline"): "auditor",
    ("GET", "/timeline/stream"): "auditor",
    ("GET", "/rules"): "auditor",
    ("GET", "/findings"): "auditor",
    ("GET", "/findings/stream"): "auditor",
    ("GET", "/graph/stream"): "auditor",
    ("GET", "/graph"): "auditor",
    ("GET", "/resource"): "auditor",
    ("GET", "/explain"): "auditor",
    ("GET", "/sparql"): "auditor",
    ("POST", "/sparql"): "auditor",
    ("GET", "/query"): "auditor",
    ("POST", "/query/validate"): "auditor",
    ("GET", "/sparql/examples"): "auditor",
    ("GET", "/logs/server"): "admin",
    ("GET", "/ledger"): "auditor",
    ("GET", "/ledger/verify"): "auditor",
    ("GET", "/ledger/{log_id}"): "auditor",
    ("POST", "/shared-context/resolve"): "logger",
    ("POST", "/shared-context/reconcile"): "admin",
    ("GET", "/shared-context/stats"): "auditor",
    ("GET", "/shared-context/review/pending"): "admin",
    ("POST", "/shared-context/review/{case_id}/accept"): "admin",
    ("POST", "/shared-context/review/{case_id}/reject"): "admin",
    ("POST", "/humans/erase"): "admin",
    ("GET", "/humans/{iri}/export"): "admin",
    ("GET", "/evidence"): "auditor",
    ("GET", "/.well-known/segb-evidence-key"): PUBLIC,
    ("GET", "/webhooks/deliveries"): "admin",
    ("POST", "/webhooks/deliveries/{delivery_id}/redeliver"): "admin",
}
# A well-formed request for each route, so an authorised caller is served (a 404 from /explain once the
# graph has been cleared is an answer, not a refusal).
IRI = "https://example.org/segb/robots/ari/v1/robot_ari"
REQUESTS: dict[tuple[str, str], dict[str, object]] = {
    ("POST", "/ttl"): {"json": {"ttl_content": f"<{IRI}> a <http://kb.openrobots.org#Robot> .", "user": "ari"}},
    ("POST", "/ttl/validate"): {"json": {"ttl_content": f"<{IRI}> a <http://kb.openrobots.org#Robot> ."}},
    ("POST", "/ttl/delete_all"): {"json": {"user": "admin"}},
    ("GET", "/ledger/{log_id}"): {"path": "/ledger/no-such-receipt"},
    ("GET", "/resource"): {"params": {"iri": IRI}},
    ("GET", "/explain"): {"params": {"iri": IRI}},
    ("GET", "/timeline"): {"params": {"robot": IRI}},
    ("GET", "/timeline/stream"): {"path": f"/timeline/stream?robot={IRI}"},
    ("GET", "/sparql"): {"params": {"query": "ASK { ?s ?p ?o }"}},
    ("POST", "/sparql"): {"content": "ASK { ?s ?p ?o }", "headers": {"Content-Type": "application/sparql-query"}},
    ("GET", "/query"): {"params": {"query": "SELECT * WHERE { ?s ?p ?o } LIMIT 1"}},
    ("POST", "/query/validate"): {"json": {"query": "SELECT * WHERE { ?s ?p ?o }"}},
    ("POST", "/shared-context/resolve"): {
        "json": {"event_kind": "human_utterance", "observed_at": "2026-05-04T10:00:00Z", "text": "hi"}
    },
    ("POST", "/shared-context/review/{case_id}/accept"): {
        "path": "/shared-context/review/review_000000000000/accept",
        "json": {"target_context_uri": "https://gsi.upm.es/segb/shared-events/x"},
    },
    ("POST", "/shared-context/review/{case_id}/reject"): {"path": "/shared-context/review/review_000000000000/reject"},
    ("POST", "/humans/erase"): {"json": {"iri": "https://example.org/h/nobody", "reason": "request 1"}},
    ("GET", "/humans/{iri}/export"): {"path": "/humans/https%3A%2F%2Fexample.org%2Fh%2Fnobody/export"},
}


@pytest.fixture(scope="module")
def server() -> Iterator[InProcess]:
    with InProcess(create_app(make_settings(secret_key=SECRET))) as served:
        yield served


def token(*roles: str, secret: str = SECRET, expires_in: int = 600) -> str:
    return mint_token(secret, username="tester", roles=roles, expires_in=expires_in).token


def call(server: InProcess, route: tuple[str, str], bearer: str | None) -> httpx.Response:
    method, path = route
    spec = dict(REQUESTS.get(route, {}))
    url = str(spec.pop("path", path))
    headers = dict(spec.pop("headers", {}))  # type: ignore[call-overload]
    if bearer is not None:
        headers["Authorization"] = f"Bearer {bearer}"
    if path.endswith("/stream"):  # an endless event stream: its status and headers are the answer
        with server.client.stream(method, url, headers=headers) as streamed:
            if streamed.status_code >= 400:
                streamed.read()
            return streamed
    return server.client.request(method, url, headers=headers, **spec)  # type: ignore[arg-type]


def served(answer: httpx.Response) -> bool:
    """Let in: a success, or an answer about the request's own target (a 404 from /explain once the graph is
    cleared; the reference's 422 for the made-up review case)."""
    if answer.status_code < 400:
        return True
    body = answer.json()
    return (answer.status_code, body["error"]) == (404, "not_found") or (
        answer.status_code == 422 and body.get("parameter") == "case_id"
    )


def test_every_route_has_a_decided_role(server: InProcess) -> None:
    paths = server.get("/openapi.json").json()["paths"]
    routes = {(method.upper(), path) for path, operations in paths.items() for method in operations}
    assert routes == set(REQUIRED_ROLE)


BAD_TOKENS = {
    "no token": None,
    "expired": lambda: mint_token(SECRET, username="t", roles=["admin"], now=time.time() - 7200, expires_in=60).token,
    "bad signature": lambda: token("admin", secret="another-secret-that-is-also-long-enough-x"),
    "alg none": lambda: jwt.encode(
        {"username": "t", "roles": ["admin"], "exp": int(time.time()) + 600}, key=None, algorithm="none"
    ),
    "garbage": lambda: "not.a.token",
}


@pytest.mark.parametrize("route", sorted(REQUIRED_ROLE), ids=lambda r: f"{r[0]} {r[1]}")
@pytest.mark.parametrize("kind", sorted(BAD_TOKENS))
def test_protected_routes_refuse_callers_without_a_valid_token(server: InProcess, route, kind: str) -> None:  # type: ignore[no-untyped-def]
    make = BAD_TOKENS[kind]
    answer = call(server, route, make() if make else None)
    if REQUIRED_ROLE[route] is PUBLIC:
        assert served(answer), answer.text
    else:
        assert answer.status_code == 401, answer.text
        assert answer.headers["www-authenticate"].startswith("Bearer")
        assert answer.json()["status"] == 401


def test_an_authorization_of_another_scheme_is_told_a_bearer_token_is_expected(server: InProcess) -> None:
    missing = server.client.get("/reports")
    assert missing.json()["detail"] == "Authorization header is required"  # the reference's words
    basic = server.client.get("/reports", headers={"Authorization": "Basic YWRtaW46YWRtaW4="})
    assert basic.status_code == 401 and "Bearer <token>" in basic.json()["detail"]


@pytest.mark.parametrize("route", sorted(REQUIRED_ROLE), ids=lambda r: f"{r[0]} {r[1]}")
@pytest.mark.parametrize("role", ["logger", "auditor", "admin"])
def test_each_role_gets_exactly_its_routes(server: InProcess, route, role: str) -> None:  # type: ignore[no-untyped-def]
    needed = REQUIRED_ROLE[route]
    allowed = needed in (PUBLIC, ANY_TOKEN) or role in (needed, "admin")
    answer = call(server, route, token(role))
    if allowed:
        assert served(answer), answer.text
    else:
        assert answer.status_code == 403, answer.text
        assert answer.json()["detail"] == "User does not have permission to perform this action"  # the reference's


def test_with_auth_off_every_route_is_open(memory_api: InProcess) -> None:
    for route in REQUIRED_ROLE:
        assert served(call(memory_api, route, None)), route


def test_the_pypi_client_publishes_with_a_logger_token_and_is_refused_without(server: InProcess) -> None:
    from tests.support.scenarios import lobby

    scenario = lobby()
    scenario.run_steps()
    ari = scenario.loggers["ari"]
    with pytest.raises(RuntimeError, match="HTTP 401"):
        ari.publish(publisher_for(server.client))
    with pytest.raises(RuntimeError, match="HTTP 403"):
        ari.publish(publisher_for(server.client, token=token("auditor")))
    answer = ari.publish(publisher_for(server.client, "admin", token("logger")))
    assert answer["user"] == "tester" and answer["claimed_user"] == "admin"  # a claim cannot impersonate
    assert answer["triples_received"] == len(ari.graph)
