"""Every endpoint of the reference backend, driven through the whole app in process with the requests its web UI, its
PyPI client and its simulation scripts send, on the embedded store and on a real Virtuoso: the statuses and JSON keys
they read, and the reference's 422 for client errors on its own endpoints."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

import httpx
import pytest
from rdflib import Graph, Namespace

from segb_server.backend.api.app import create_app
from tests.api.test_compat_validate import unreachable_store
from tests.conftest import FIXTURES, make_settings
from tests.support.in_process import InProcess, publisher_for

# What the reference web UI's HTTP client sends with every call.
UI_ACCEPT = {"Accept": "application/json, text/plain, text/turtle"}
EX = Namespace("http://example.org/")
AT = datetime(2026, 5, 4, 10, 0, 0, tzinfo=UTC)
MARIA = "https://example.org/people/maria"

VALIDATION_KEYS = {"valid", "syntax_ok", "semantic_ok", "triple_count", "issues"}
ISSUE_KEYS = {"severity", "code", "message", "focus_node", "predicate", "value"}
QUERY_VALIDATION_KEYS = {"valid", "query_kind", "allows_update_execution", "message"}
LOG_KEYS = {"log_file", "count", "filters", "entries"}
LOG_ENTRY_KEYS = {"timestamp", "level", "logger", "request_id", "actor", "origin_ip", "message", "raw"}
RESOLVE_KEYS = {
    "shared_context_uri",
    "status",
    "confidence",
    "matched_candidate_uri",
    "close_candidates",
    "score_breakdown",
    "candidate_count",
    "resolver_version",
}
RECONCILE_KEYS = {"scanned_ambiguous", "merged_count", "mappings", "resolver_version", "pending_cases"}
STATS_KEYS = {"resolver_version", "active_contexts", "ambiguous_contexts", "merged_contexts", "aliases"}
QUEUE_KEYS = {
    "resolver_version",
    "unresolved_count",
    "pending_count",
    "unresolved_contexts",
    "contexts",
    "pending_cases",
}
RECORD_KEYS = {
    "uri",
    "event_kind",
    "status",
    "observed_at",
    "subject_uri",
    "modality",
    "canonical_text",
    "observation_count",
    "observations",
}
OBSERVATION_KEYS = {"observed_at", "subject_uri", "modality", "text", "observation_uri", "robot_uri"}
CASE_KEYS = {
    "case_id",
    "source_context_uri",
    "candidates",
    "status",
    "created_at",
    "decided_at",
    "selected_context_uri",
}
DECISION_KEYS = {
    "case_id",
    "status",
    "source_context_uri",
    "selected_context_uri",
    "resulting_context_uri",
    "resolver_version",
}


def call(server: InProcess, method: str, path: str, **kwargs: Any) -> httpx.Response:
    kwargs["headers"] = {**UI_ACCEPT, **kwargs.get("headers", {})}
    return server.client.request(method, path, **kwargs)


def json_of(answer: httpx.Response, status: int = 200) -> Any:
    assert answer.status_code == status, answer.text
    assert answer.headers["content-type"].startswith("application/json")
    return answer.json()


def refused_422(answer: httpx.Response) -> dict[str, Any]:
    """A client error as the reference answers it: 422, and a string the reference UI can show (`detail` for a
    domain error, `message` for a malformed request, whose `detail` is the list of problems)."""
    body = json_of(answer, 422)
    assert isinstance(body["detail"], str) or isinstance(body["message"], str)
    return body


def utterance(seconds: float, subject: str | None = MARIA) -> dict[str, Any]:
    """What HTTPSharedContextResolver posts, plus the robot and observation the simulation scripts add."""
    return {
        "event_kind": "human_utterance",
        "observed_at": (AT + timedelta(seconds=seconds)).isoformat(),
        "subject_uri": subject,
        "modality": "speech",
        "text": "Good morning, robot!",
        "robot_uri": "https://example.org/robots/ari",
        "observation_uri": f"https://example.org/observations/{seconds}",
    }


def test_health_auth_mode_and_docs(api: InProcess) -> None:
    assert json_of(call(api, "GET", "/healthz/live")) == {"live": True}
    ready = json_of(call(api, "GET", "/healthz/ready"))
    assert ready["ready"] is True and len(ready) == 2  # {"ready": true, "virtuoso": true} on Virtuoso
    assert json_of(call(api, "GET", "/auth/mode"))["auth_enabled"] is False
    for path in ("/docs", "/redoc", "/openapi.json"):
        assert call(api, "GET", path).status_code == 200, path


def test_the_insert_page_the_kg_page_and_the_delete_page(api: InProcess) -> None:
    turtle = (FIXTURES / "reference_uc01.ttl").read_text()
    # The insert page validates first, then inserts; the client library posts the same body with a user.
    validation = json_of(call(api, "POST", "/ttl/validate", json={"ttl_content": turtle}))
    assert set(validation) >= VALIDATION_KEYS and validation["valid"] is True
    inserted = publisher_for(api.client, "ari").publish_turtle(turtle)
    assert {"message", "log_id"} <= set(inserted) and inserted["log_id"]
    ui_insert = call(api, "POST", "/ttl", json={"ttl_content": turtle})
    assert ui_insert.status_code == 201 and json_of(ui_insert, 201)["log_id"]

    events = call(api, "GET", "/events")
    assert (events.status_code, events.headers["content-type"]) == (200, "text/turtle; charset=utf-8")
    assert len(Graph().parse(data=events.text, format="turtle")) == validation["triple_count"]

    # The delete page posts {}; the client library posts {"user": …}.
    assert json_of(call(api, "POST", "/ttl/delete_all", json={}))["message"] == "Graph cleared."
    assert publisher_for(api.client).delete_all_ttls(user="admin")["message"] == "No TTLs to delete"
    assert len(Graph().parse(data=call(api, "GET", "/events").text, format="turtle")) == 0


def test_the_query_workbench(api: InProcess) -> None:
    publisher_for(api.client).publish_turtle((FIXTURES / "reference_uc01.ttl").read_text())
    query = "SELECT ?s ?p ?o WHERE { ?s ?p ?o } LIMIT 20"  # the workbench's prefilled query
    checked = json_of(call(api, "POST", "/query/validate", json={"query": query}))
    assert set(checked) >= QUERY_VALIDATION_KEYS
    assert (checked["valid"], checked["query_kind"], checked["allows_update_execution"]) == (True, "select", False)
    answer = call(api, "GET", "/query", params={"query": query})
    assert (answer.status_code, answer.headers["content-type"]) == (200, "text/turtle; charset=utf-8")
    rows = set(Graph().parse(data=answer.text, format="turtle").subjects(predicate=None, object=EX.Result))
    assert len(rows) == 20

    update = json_of(call(api, "POST", "/query/validate", json={"query": "CLEAR ALL"}))
    assert (update["valid"], update["query_kind"]) == (False, "update")


def test_the_reference_client_errors_of_the_query_endpoints_are_422(memory_api: InProcess) -> None:
    refused_422(call(memory_api, "GET", "/query"))
    for query in ("CLEAR ALL", "SELECT ?s WHERE {", "HELLO"):
        body = refused_422(call(memory_api, "GET", "/query", params={"query": query}))
        assert isinstance(body["detail"], str), query
    refused_422(call(memory_api, "POST", "/query/validate", json={}))
    refused_422(call(memory_api, "POST", "/query/validate", json={"query": 42}))
    # The standard endpoint keeps the protocol's 400.
    assert call(memory_api, "GET", "/sparql", params={"query": "CLEAR ALL"}).status_code == 400


def test_the_system_logs_page(memory_api: InProcess) -> None:
    call(memory_api, "GET", "/healthz/live", headers={"X-Request-ID": "logs-page-1"})
    body = json_of(
        call(memory_api, "GET", "/logs/server", params={"limit": 200, "level": "INFO", "contains": "logs-page"})
    )
    assert set(body) >= LOG_KEYS
    assert body["filters"] == {"limit": 200, "level": "INFO", "contains": "logs-page"}
    [entry] = body["entries"]
    assert set(entry) >= LOG_ENTRY_KEYS and body["count"] == 1
    assert (entry["request_id"], entry["origin_ip"], entry["level"]) == ("logs-page-1", "127.0.0.1", "INFO")
    assert json_of(call(memory_api, "GET", "/logs/server", params={"limit": 2000}))["filters"]["limit"] == 2000
    for params in ({"limit": 0}, {"limit": 2001}, {"level": "LOUD"}):
        refused_422(call(memory_api, "GET", "/logs/server", params=params))


def test_the_shared_context_console_and_the_simulation_scripts(memory_api: InProcess) -> None:
    first = json_of(call(memory_api, "POST", "/shared-context/resolve", json=utterance(0)))
    assert set(first) >= RESOLVE_KEYS and first["status"] == "created"
    assert json_of(call(memory_api, "POST", "/shared-context/resolve", json=utterance(0.8)))["status"] == "matched"
    ambiguous = json_of(call(memory_api, "POST", "/shared-context/resolve", json=utterance(1.3, subject=None)))
    assert ambiguous["status"] == "ambiguous"

    assert set(json_of(call(memory_api, "POST", "/shared-context/reconcile", json={}))) >= RECONCILE_KEYS
    assert set(json_of(call(memory_api, "GET", "/shared-context/stats"))) >= STATS_KEYS
    queue = json_of(call(memory_api, "GET", "/shared-context/review/pending"))
    assert set(queue) >= QUEUE_KEYS and queue["pending_count"] == 1
    for record in queue["unresolved_contexts"] + queue["contexts"]:
        assert set(record) >= RECORD_KEYS
        assert all(set(observation) >= OBSERVATION_KEYS for observation in record["observations"])
    [case] = queue["pending_cases"]
    assert set(case) >= CASE_KEYS
    assert set(case["candidates"][0]) >= {"context_uri", "score", "score_breakdown"}

    target = case["candidates"][0]["context_uri"]
    accept = f"/shared-context/review/{case['case_id']}/accept"
    accepted = json_of(call(memory_api, "POST", accept, json={"target_context_uri": target}))
    assert set(accepted) >= DECISION_KEYS
    assert (accepted["status"], accepted["resulting_context_uri"]) == ("accepted", target)


def test_the_reference_client_errors_of_the_review_endpoints_are_422(memory_api: InProcess) -> None:
    json_of(call(memory_api, "POST", "/shared-context/resolve", json=utterance(0)))
    source = json_of(call(memory_api, "POST", "/shared-context/resolve", json=utterance(0.5, subject=None)))
    [case] = json_of(call(memory_api, "GET", "/shared-context/review/pending"))["pending_cases"]
    accept, reject = (f"/shared-context/review/{case['case_id']}/{decision}" for decision in ("accept", "reject"))

    for body in ({}, {"target_context_uri": ""}, {"target_context_uri": source["shared_context_uri"]}):
        refused_422(call(memory_api, "POST", accept, json=body))  # missing, blank, the source itself
    refused_422(call(memory_api, "POST", accept, json={"target_context_uri": "https://example.org/not-a-candidate"}))
    for unknown in ("/shared-context/review/review_000000000000/accept", "/shared-context/review/no such case/reject"):
        body = refused_422(call(memory_api, "POST", unknown, json={"target_context_uri": "https://x.org/"}))
        assert "case" in str(body["detail"]).lower()

    rejected = json_of(call(memory_api, "POST", reject, json={}))  # the scripts post {}
    assert set(rejected) >= DECISION_KEYS
    assert (rejected["status"], rejected["selected_context_uri"], rejected["resulting_context_uri"]) == (
        "rejected",
        None,
        None,
    )
    for decided in (reject, accept):  # no longer pending
        detail = refused_422(call(memory_api, "POST", decided, json={"target_context_uri": "https://x.org/"}))["detail"]
        assert "not pending" in detail

    for bad in ({**utterance(0), "event_kind": "  "}, {**utterance(0), "observed_at": "yesterday"}, {"text": "hi"}):
        refused_422(call(memory_api, "POST", "/shared-context/resolve", json=bad))


@pytest.mark.parametrize("path", ["/events", "/query?query=ASK%20%7B%7D", "/ttl", "/ttl/delete_all"])
def test_the_store_routes_answer_503_when_the_store_is_down(path: str) -> None:
    """As the reference's 503 "Virtuoso is unavailable", with the JSON error shape; validation needs no store."""
    store = unreachable_store()
    method = "POST" if path.startswith("/ttl") else "GET"
    body = {"ttl_content": "<https://example.org/a> a <https://example.org/B> ."} if path == "/ttl" else {}
    try:
        with InProcess(create_app(make_settings(), store=store)) as server:
            answer = call(server, method, path, json=body) if method == "POST" else call(server, method, path)
    finally:
        store.close()
    assert (answer.status_code, answer.json()["error"]) == (503, "store_unavailable"), answer.text
