"""Liveness and readiness probes: exact bodies, 503 when the store is gone, answers during heavy ingest."""

from __future__ import annotations

import shutil
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.store.base import QueryResult, StoreRejectedQuery, StoreUnavailable
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings, virtuoso_store
from tests.support.in_process import InProcess, Server, http
from tests.support.live_server import LiveServer
from tests.support.settle import kept_rows, settle
from tests.support.virtuoso import VirtuosoProcess

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
EX_LATE = "https://example.org/late/"
# A robot and a person it heard, posted once a view is set aside: a new row of the participants report.
LATE_PARTICIPANT = (
    f'<{EX_LATE}robot> a <http://kb.openrobots.org#Robot> ; <http://schema.org/name> "Late robot" .\n'
    f"<{EX_LATE}human> a <http://kb.openrobots.org#Human> .\n"
    f"<{EX_LATE}message> <http://www.w3.org/ns/prov#wasGeneratedBy> <{EX_LATE}heard> ;\n"
    f"    <http://schema.org/sender> <{EX_LATE}human> .\n"
    f"<{EX_LATE}heard> <http://www.gsi.upm.es/ontologies/segb/ns#wasPerformedBy> <{EX_LATE}robot> ;\n"
    '    <http://www.w3.org/ns/prov#startedAtTime> "2026-03-10T10:00:00Z"'
    "^^<http://www.w3.org/2001/XMLSchema#dateTime> ."
)


def test_live_and_ready_on_the_embedded_store(tmp_path: Path) -> None:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        live = server.get("/healthz/live")
        ready = server.get("/healthz/ready")
    assert (live.status_code, live.text) == (200, '{"live": true}')
    assert (ready.status_code, ready.text) == (200, '{"ready": true, "oxigraph": true}')


@pytest.mark.virtuoso
def test_readiness_follows_virtuoso_down_and_back_without_a_restart(tmp_path: Path) -> None:
    process = VirtuosoProcess(tmp_path)
    process.start()
    store = virtuoso_store(process, "http://amor-segb/events")
    try:
        with InProcess(create_app(make_settings(store="virtuoso"), store=store)) as server:
            up = server.get("/healthz/ready")
            assert (up.status_code, up.text) == (200, '{"ready": true, "virtuoso": true}')

            process.stop()
            down = server.get("/healthz/ready")
            assert down.status_code == 503
            assert down.json()["ready"] is False and down.json()["virtuoso"] is False
            # Kept in the journal, but not applied: 503 with Retry-After, saying so.
            waiting = server.post("/ttl", json={"ttl_content": "<https://e.org/a> <https://e.org/b> 1 ."})
            assert waiting.status_code == 503 and waiting.headers["retry-after"]
            assert "kept in the journal" in waiting.json()["detail"] and "virtuoso" in waiting.json()["detail"]

            process.start()
            assert wait_until_ready(server.client).status_code == 200
            settle(server.client)  # the kept post applied and in the reports' rows: nothing behind, nothing to say
            back = server.get("/healthz/ready")
            assert (back.status_code, back.text) == (200, '{"ready": true, "virtuoso": true}')
            assert store.count() == 1  # the post kept while Virtuoso was down was applied once it came back
            again = server.post("/ttl", json={"ttl_content": "<https://e.org/a> <https://e.org/b> 1 ."})
            assert (again.status_code, again.json()["triples_new"]) == (201, 0)
    finally:
        store.close()
        process.stop()


def wait_until_ready(server: Server, timeout: float = 30) -> httpx.Response:
    """Readiness once the store answers and the journal is applied (the applier retries on its own); `server`:
    a live server's URL or the client of an app served in process."""
    deadline = time.monotonic() + timeout
    while True:
        answer = http(server, "GET", "/healthz/ready")
        if (answer.status_code == 200 and "apply_lag" not in answer.json()) or time.monotonic() > deadline:
            return answer
        time.sleep(0.1)


@pytest.mark.slow
def test_health_keeps_answering_while_a_large_ingest_runs(tmp_path: Path) -> None:
    """Behaviour, not a wall-clock figure (that is bench's "health under load"): readiness probes keep being
    answered, one after another, while one large post is still being ingested."""
    payload = "".join(
        f'<https://ex.org/robot/r{i % 16}/event/{i}> <https://ex.org/says> "utterance number {i}" .\n'
        for i in range(250_000)
    ).encode()
    store = OxigraphStore("http://amor-segb/events", tmp_path / "store")
    answered_during_ingest = 0
    with InProcess(create_app(make_settings(store="oxigraph"), store=store)) as server:
        ingest = threading.Thread(
            target=lambda: server.post(
                "/ttl", content=payload, headers={"Content-Type": "application/n-triples"}
            ).raise_for_status()
        )
        ingest.start()
        while ingest.is_alive():
            assert server.get("/healthz/ready").status_code == 200
            answered_during_ingest += ingest.is_alive()  # counted only if the ingest had not answered yet
        ingest.join()
    assert store.count() == 250_000
    assert answered_during_ingest >= 10, "health was not answered while the ingest ran: it waited behind it"
    store.close()


def ready_with_only_set_aside(client: httpx.Client, view: str, timeout: float = 60) -> dict[str, Any]:
    """Readiness once every view but `view` is built and current (`view` set aside, its error told)."""
    deadline = time.monotonic() + timeout
    while (body := client.get("/healthz/ready").json()).get("views_building") != [view] or "reports_lag" in body:
        assert time.monotonic() < deadline, body
        time.sleep(0.05)
    assert body["ready"] is True and "views_error" in body, body
    return body


def rows_with(client: httpx.Client, path: str, text: str, timeout: float = 60) -> dict[str, Any]:
    """The first page of report `path` once it holds `text`."""
    deadline = time.monotonic() + timeout
    while text not in (page := client.get(path)).text:
        assert time.monotonic() < deadline, page.text
        time.sleep(0.05)
    answer: dict[str, Any] = page.json()
    return answer


class RefusingStore(OxigraphStore):
    """The embedded store failing the emotion-timeline report's query with `error` while `refusing` is set, as
    a store may refuse one query (too costly, a limit of its own) or let it run past the wait for its answer,
    and answer every other (its pings included)."""

    refusing = True

    def __init__(self, path: Path, error: Exception) -> None:
        super().__init__("http://amor-segb/events", path)
        self.error = error

    def query(self, sparql: str, bindings: Any = None, timeout: float | None = None) -> QueryResult:
        if self.refusing and "targetKind" in sparql and "param_threshold" in sparql:
            raise self.error
        return super().query(sparql, bindings, timeout)


@pytest.mark.parametrize(
    "error",
    [
        StoreRejectedQuery("the store refused the emotion timeline's query"),
        StoreUnavailable("the store did not answer the emotion timeline's query in time: ReadTimeout"),
    ],
    ids=["refused", "timed-out"],
)
@pytest.mark.parametrize("when", ["built", "kept"])
def test_readiness_tells_why_a_view_stays_behind_and_the_views_after_it_are_built(
    tmp_path: Path, error: Exception, when: str
) -> None:
    """A view whose query the store refuses, or does not answer in time while it answers pings — as the view is
    built at start, or once kept, as a post reaches its rows — neither holds the other views back nor goes
    unexplained: readiness names it as still being built with the error
    retried (`views_error`), the other reports are kept current in their rows, and once the store answers
    everything is built and readiness is exact again."""
    store = RefusingStore(tmp_path / "store", error)
    store.refusing = when == "built"  # as the view is built at start, or once kept, as a post reaches its rows
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path / "data"), store=store)) as server:
        if when == "kept":
            kept_rows(server.client, "emotion-timeline")
            store.refusing = True
        post_two_robots(server.client)
        body = ready_with_only_set_aside(server.client, "reports/emotion-timeline")
        assert body["views_error"] == f"reports/emotion-timeline: {error}"
        assert server.post("/ttl", json={"ttl_content": LATE_PARTICIPANT, "user": "r"}).status_code == 201
        assert rows_with(server.client, "/reports/participants", "Late robot")["served_from"] == "rows"
        store.refusing = False
        settle(server.client)
        ready = server.get("/healthz/ready")
        assert (ready.status_code, ready.text) == (200, '{"ready": true, "oxigraph": true}')
        assert server.get("/reports/emotion-timeline", params={"limit": 1}).json()["served_from"] == "rows"
    store.close()


# A report Virtuoso 7 cannot answer once a robot's name is not a time: SPARQL makes a failed cast unbound (the
# embedded store does), Virtuoso fails the whole query ("Cannot convert ... to datetime").
NAME_AS_TIME_REPORT = """# title: Robots' names as times
# key: ?robot
# description: Every robot and its name read as a time (none for a name that is not one).
PREFIX xsd: <http://www.w3.org/2001/XMLSchema#>
PREFIX schema: <http://schema.org/>
PREFIX oro: <http://kb.openrobots.org#>
SELECT ?robot ?name ?time WHERE { ?robot a oro:Robot ; schema:name ?name . BIND (xsd:dateTime(?name) AS ?time) }
ORDER BY ?robot
"""


@pytest.mark.virtuoso
def test_a_report_virtuoso_refuses_is_set_aside_and_told_while_the_others_are_kept(
    virtuoso: VirtuosoProcess, tmp_path: Path
) -> None:
    """On a real Virtuoso, a report an operator adds to a store holding robots, whose query Virtuoso refuses, is
    the only view not built at the next start: readiness names it with Virtuoso's own error, and the other
    reports are kept current."""
    sparql = tmp_path / "sparql"
    shutil.copytree(PACKAGE_ROOT / "sparql", sparql)
    report = sparql / "reports" / "robot-name-times.rq"
    store = virtuoso_store(virtuoso)
    settings = make_settings(store="virtuoso", data_dir=tmp_path / "data", sparql_dir=sparql)
    try:
        # Posted by a server without the report, which the next start adds.
        with LiveServer(create_app(settings, store=virtuoso_store(virtuoso, store.graph_uri))) as live:
            post_two_robots(live.client)
            settle(live.client)
        report.write_text(NAME_AS_TIME_REPORT)
        with LiveServer(create_app(settings, store=store)) as live:
            body = ready_with_only_set_aside(live.client, "reports/robot-name-times")
            assert body["views_error"].startswith("reports/robot-name-times: "), body
            assert "Cannot convert" in body["views_error"], body
            assert live.client.post("/ttl", json={"ttl_content": LATE_PARTICIPANT, "user": "r"}).status_code == 201
            assert rows_with(live.client, "/reports/participants", "Late robot")["served_from"] == "rows"
            assert ready_with_only_set_aside(live.client, "reports/robot-name-times") == body
    finally:
        store.clear()
        store.close()


def post_two_robots(client: httpx.Client) -> None:
    posted = client.post("/ttl", json={"ttl_content": (FIXTURES / "sample_two_robots.ttl").read_text(), "user": "r"})
    assert posted.status_code == 201, posted.text
