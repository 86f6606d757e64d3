"""A report is added by dropping a `.rq` file in `sparql/reports/`, no Python: with a `# key:` line its rows
are kept current; with a construct the rows cannot follow (here MINUS) it is evaluated in full, and says so.
A filter on a parameter through EXISTS is served from the rows with everything its body says, VALUES too. A
`same-as` preset is served from its base's rows, kept once."""

from __future__ import annotations

import json
import logging
import shutil
import sqlite3
from collections.abc import Iterator
from contextlib import closing
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.container import REPORTS_FILE
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.in_process import InProcess, Server, http
from tests.support.live_server import LiveServer
from tests.support.settle import settle
from tests.support.streams import first_event

PREFIXES = """PREFIX rdf: <http://www.w3.org/1999/02/22-rdf-syntax-ns#>
PREFIX foaf: <http://xmlns.com/foaf/0.1/>
PREFIX prov: <http://www.w3.org/ns/prov#>
"""
# Agents with a first name: kept as rows, one row per agent.
NAMED = f"""# title: Named agents
# key: ?agent
# description: Every agent with a first name.
{PREFIXES}
SELECT ?agent ?name WHERE {{
  ?agent foaf:firstName ?name .
}}
ORDER BY ?name ?agent
"""
# Agents without a first name: MINUS is beyond what the rows can follow.
UNNAMED = f"""# title: Unnamed agents
# key: ?agent
# description: Every agent without a first name.
{PREFIXES}
SELECT ?agent WHERE {{
  ?agent a prov:Agent .
  MINUS {{ ?agent foaf:firstName ?name }}
}}
ORDER BY ?agent
"""

# Agents who know the given person: the EXISTS body narrows the friend's class with VALUES.
BY_FRIEND = f"""# title: Agents by friend
# key: ?agent
# description: Every agent with a first name, or only those who know the given person.
# param friend: iri — only agents who know this person
{PREFIXES}
SELECT ?agent ?name WHERE {{
  ?agent foaf:firstName ?name .
  FILTER (!BOUND(?param_friend)
          || EXISTS {{ ?agent foaf:knows ?param_friend . ?param_friend a ?kind . VALUES ?kind {{ foaf:Person }} }})
}}
ORDER BY ?name ?agent
"""

# The same query with a friend chosen by default: a preset, whose rows are its base's.
FRIENDS_OF_001 = """# title: Friends of P001
# same-as: reports/agents-by-friend
# param friend: iri = https://example.org/p/001 — only agents who know this person
"""


def people(count: int, start: int = 0) -> str:
    lines = [f"<https://example.org/p/{i:03d}> a <http://www.w3.org/ns/prov#Agent> ." for i in range(start, count)]
    lines += [
        f'<https://example.org/p/{i:03d}> <http://xmlns.com/foaf/0.1/firstName> "P{i:03d}" .'
        for i in range(start, count)
        if i % 2 == 0
    ]
    return "\n".join(lines)


def with_added_reports(tmp_path: Path) -> Path:
    """The shipped queries and this module's reports, in a folder of their own."""
    sparql = tmp_path / "sparql"
    shutil.copytree(PACKAGE_ROOT / "sparql", sparql)
    (sparql / "reports" / "named-agents.rq").write_text(NAMED)
    (sparql / "reports" / "unnamed-agents.rq").write_text(UNNAMED)
    (sparql / "reports" / "agents-by-friend.rq").write_text(BY_FRIEND)
    (sparql / "reports" / "friends-of-001.rq").write_text(FRIENDS_OF_001)
    return sparql


class _Records(logging.Handler):
    """Every record of a logger while a server runs: pytest's own capture has a handler for each phase of a
    test, and a record a server's thread logs between two phases is captured by neither."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@pytest.fixture
def reports_log() -> Iterator[_Records]:
    logger, records = logging.getLogger("segb.reports"), _Records()
    level = logger.level
    logger.setLevel(logging.INFO)
    logger.addHandler(records)
    yield records
    logger.removeHandler(records)
    logger.setLevel(level)


@pytest.fixture
def server(tmp_path: Path, reports_log: _Records) -> Iterator[httpx.Client]:
    with InProcess(create_app(make_settings(sparql_dir=with_added_reports(tmp_path)))) as served:
        yield served.client


@pytest.fixture
def live_server(tmp_path: Path) -> Iterator[str]:
    """Over real HTTP, for reading a stream with a time limit."""
    with LiveServer(create_app(make_settings(sparql_dir=with_added_reports(tmp_path)))) as live:
        yield live.url


def post(server: Server, turtle: str) -> None:
    answer = http(server, "POST", "/ttl", json={"ttl_content": turtle, "user": "test"})
    assert answer.status_code == 201, answer.text


def test_a_keyed_report_is_kept_as_rows_and_follows_new_posts(server: httpx.Client) -> None:
    post(server, people(10))
    settle(server)
    body = server.get("/reports/named-agents", params={"limit": 3}).json()
    assert body["served_from"] == "rows"
    assert [row["name"] for row in body["rows"]] == ["P000", "P002", "P004"]
    rest = server.get("/reports/named-agents", params={"limit": 3, "after": body["next"]}).json()
    assert [row["name"] for row in rest["rows"]] == ["P006", "P008"]
    assert rest["has_more"] is False

    post(server, people(12, start=10))
    settle(server)
    names = [row["name"] for row in server.get("/reports/named-agents").json()["rows"]]
    assert names == ["P000", "P002", "P004", "P006", "P008", "P010"]


def test_a_report_the_rows_cannot_follow_is_evaluated_in_full(server: httpx.Client) -> None:
    post(server, people(6))
    settle(server)
    body = server.get("/reports/unnamed-agents").json()
    assert body["served_from"] == "query"
    assert body["next"] is None
    assert [row["agent"] for row in body["rows"]] == [f"https://example.org/p/{i:03d}" for i in (1, 3, 5)]
    refused = server.get("/reports/unnamed-agents", params={"after": body["rows"][0]["agent"]})
    assert refused.status_code == 422
    assert "after" in refused.json()["detail"] and "offset" in refused.json()["detail"]


def test_a_filter_through_exists_keeps_the_values_its_body_narrows_to(server: httpx.Client) -> None:
    """P000 knows P001, a person; P002 knows P003, an agent but not a person: only P000 knows a person."""
    person, agent = "http://xmlns.com/foaf/0.1/Person", "http://www.w3.org/ns/prov#Agent"
    knows = "http://xmlns.com/foaf/0.1/knows"
    post(server, people(4))
    post(
        server,
        f"""<https://example.org/p/000> <{knows}> <https://example.org/p/001> .
<https://example.org/p/001> a <{person}> .
<https://example.org/p/002> <{knows}> <https://example.org/p/003> .
<https://example.org/p/003> a <{agent}> .""",
    )
    settle(server)
    for friend, expected in (("001", ["P000"]), ("003", [])):
        body = server.get("/reports/agents-by-friend", params={"friend": f"https://example.org/p/{friend}"}).json()
        assert body["served_from"] == "rows"
        assert [row["name"] for row in body["rows"]] == expected, friend


def test_a_preset_is_served_from_its_base_rows_kept_once(server: httpx.Client, reports_log: _Records) -> None:
    person, knows = "http://xmlns.com/foaf/0.1/Person", "http://xmlns.com/foaf/0.1/knows"
    post(server, people(6))
    post(server, f"<https://example.org/p/000> <{knows}> <https://example.org/p/001> .")
    post(server, f"<https://example.org/p/001> a <{person}> .")
    settle(server)
    preset = server.get("/reports/friends-of-001").json()
    assert preset["served_from"] == "rows"
    assert [row["name"] for row in preset["rows"]] == ["P000"]

    post(server, f"<https://example.org/p/004> <{knows}> <https://example.org/p/001> .")
    settle(server)
    names = [row["name"] for row in server.get("/reports/friends-of-001").json()["rows"]]
    assert names == ["P000", "P004"]
    everyone = server.get("/reports/agents-by-friend").json()
    assert [row["name"] for row in everyone["rows"]] == ["P000", "P002", "P004"]
    built = [message for message in reports_log.messages if " built: " in message]
    assert any("reports/agents-by-friend" in message for message in built), "\n".join(built)
    assert not any("reports/friends-of-001" in message for message in built), built


def test_a_preset_stream_tells_the_changes_of_the_rows_it_shares(live_server: str) -> None:
    server = live_server
    knows = "http://xmlns.com/foaf/0.1/knows"
    post(server, people(2))
    post(server, f"<https://example.org/p/000> <{knows}> <https://example.org/p/001> .")
    settle(server)
    event = first_event(f"{server}/reports/stream?report=friends-of-001", {"Last-Event-ID": "0"})  # replay all
    assert event["event"] == "change"
    assert json.loads(event["data"]) == {"report": "friends-of-001", "units": ["<https://example.org/p/000>"]}


def test_the_rows_of_a_report_no_longer_kept_are_dropped_at_the_next_start(tmp_path: Path) -> None:
    """A report removed from the catalog, or become a preset of another, leaves no tables or state behind once
    the server starts again; the reports still kept are read from their rows as before."""
    sparql = tmp_path / "sparql"
    shutil.copytree(PACKAGE_ROOT / "sparql", sparql)
    (sparql / "reports" / "named-agents.rq").write_text(NAMED)
    (sparql / "reports" / "agents-by-friend.rq").write_text(BY_FRIEND)
    (sparql / "reports" / "friends-of-001.rq").write_text(BY_FRIEND.replace("Agents by friend", "Friends of P001"))
    store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    settings = make_settings(store="oxigraph", data_dir=tmp_path / "data", sparql_dir=sparql)
    try:
        with InProcess(create_app(settings, store=store)) as live:
            post(live.client, people(6))
            settle(live.client)
        tables, states = stored_reports(settings.data_dir / REPORTS_FILE)
        assert {"report_reports_named_agents", "report_reports_friends_of_001"} <= tables
        assert {"reports/named-agents", "reports/friends-of-001"} <= states

        (sparql / "reports" / "named-agents.rq").unlink()
        (sparql / "reports" / "friends-of-001.rq").write_text(FRIENDS_OF_001)  # now a preset: its base's rows
        with InProcess(create_app(settings, store=store)) as live:
            settle(live.client)
            body = live.get("/reports/friends-of-001").json()
            assert body["served_from"] == "rows"
        tables, states = stored_reports(settings.data_dir / REPORTS_FILE)
        assert not any(
            name.startswith(("report_reports_named_agents", "report_reports_friends_of_001")) for name in tables
        ), tables
        assert {"reports/named-agents", "reports/friends-of-001"}.isdisjoint(states)
        assert {
            "report_reports_agents_by_friend",
            "report_reports_conversations",
        } <= tables and "reports/agents-by-friend" in states
    finally:
        store.close()


def stored_reports(path: Path) -> tuple[set[str], set[str]]:
    """The tables of a reports database and the reports whose state it holds."""
    with closing(sqlite3.connect(path)) as connection:
        tables = {row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        states = {row[0] for row in connection.execute("SELECT report FROM report_state")}
    return tables, states


@pytest.mark.virtuoso
def test_every_documented_page_of_a_report_evaluated_in_full_answers_on_every_store(
    store: Store, tmp_path: Path
) -> None:
    """Virtuoso sorts at most 10,000 rows for one answer (its error SR353 counts offset and limit together):
    the largest page, and pages deeper than that, of a report evaluated by its query answer all the same."""
    sparql = tmp_path / "sparql"
    shutil.copytree(PACKAGE_ROOT / "sparql", sparql)
    (sparql / "reports" / "unnamed-agents.rq").write_text(UNNAMED)
    agents = [f"https://example.org/agent/{i:05d}" for i in range(12_500)]
    with InProcess(create_app(make_settings(sparql_dir=sparql), store=store)) as live:
        post(live.client, "\n".join(f"<{agent}> a <http://www.w3.org/ns/prov#Agent> ." for agent in agents))
        settle(live.client)
        for limit, offset in ((10_000, 0), (10_000, 1), (10_000, 10_000), (100, 12_350), (100, 12_400)):
            answer = live.get("/reports/unnamed-agents", params={"limit": limit, "offset": offset})
            assert answer.status_code == 200, (limit, offset, answer.text[:300])
            body = answer.json()
            assert body["served_from"] == "query"
            assert [row["agent"] for row in body["rows"]] == agents[offset : offset + limit], (limit, offset)
            assert body["has_more"] is (offset + limit < len(agents)), (limit, offset)
