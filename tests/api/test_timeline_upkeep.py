"""The timeline kept current equals its queries evaluated in full, after every step of random histories (several
robots, links arriving late, out-of-order times, re-publishes, clearings), on both stores, paged with `next`
across kinds; and its messages' speakers are the conversations report's, message by message."""

from __future__ import annotations

import random
from collections import Counter

import httpx
import pytest
from pyoxigraph import QuerySolutions, RdfFormat
from pyoxigraph import Store as OxStore

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.timeline.events import moment
from segb_server.backend.services.values import json_value
from segb_server.backend.services.views.kept_queries.plan import declared_key
from tests.api.test_reports_differential import bound_text
from tests.support.histories import EX, HUMANS, ROBOTS, History, send
from tests.support.settle import settle

CATALOG = Catalog(PACKAGE_ROOT / "sparql")
KINDS = {query.name.removeprefix("timeline/"): query for query in CATALOG.under("timeline")}


def timeline(url: str, params: dict[str, str], page: int) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    after: str | None = None
    while True:
        answer = httpx.get(f"{url}/timeline", params={**params, "limit": page, **({"after": after} if after else {})})
        assert answer.status_code == 200, answer.text
        body = answer.json()
        assert set(body["served_from"].values()) <= {"rows"}, body["served_from"]
        rows += body["rows"]
        if not body["has_more"]:
            return rows
        after = body["next"]


def embedded_copy(url: str) -> OxStore:
    """The server's graph in an embedded store of the test's own: the oracle the timeline is checked against.
    Virtuoso 7 answers these queries wrongly with a filter bound (it skips an EXISTS in a group that opens with
    VALUES), which the server never asks of it for the timeline's kept rows (kept with no filter bound)."""
    copy = OxStore()
    answer = httpx.get(f"{url}/events", headers={"Accept": "application/n-triples"}, timeout=60)
    copy.load(answer.content, RdfFormat.N_TRIPLES)
    return copy


def evaluated_events(copy: OxStore, params: dict[str, str]) -> Counter[tuple[str, str, str]]:
    """(kind, key, time) of every event the kinds' queries give evaluated in full: a run of rows with one key and
    one time is one event, as the timeline tells it."""
    events: Counter[tuple[str, str, str]] = Counter()
    for kind, query in KINDS.items():
        if not set(params) <= set(query.parameters):
            continue  # a kind that knows no such filter (states of a human) is not on that timeline
        key = declared_key(query)[0][1:]
        previous = None
        solutions = copy.query(bound_text(query.name, params))
        assert isinstance(solutions, QuerySolutions)
        for solution in solutions:
            current = (kind, str(json_value(solution[key])), str(json_value(solution["time"])))
            if current != previous:
                events[current] += 1
            previous = current
    return events


def listed_findings(url: str, params: dict[str, str]) -> Counter[tuple[str, str, str]]:
    """(kind, key, time) of the findings `GET /findings` lists under the same filters, those with a time: the
    timeline's findings source reads that service, so its events must be these."""
    events: Counter[tuple[str, str, str]] = Counter()
    after: str | None = None
    while True:
        answer = httpx.get(f"{url}/findings", params={**params, "limit": 50, **({"after": after} if after else {})})
        assert answer.status_code == 200, answer.text
        body = answer.json()
        events.update(("finding", str(f["focus"]), str(f["time"])) for f in body["findings"] if f["time"])
        if not body["has_more"]:
            return events
        after = body["next"]


@pytest.mark.parametrize("seed", [3, pytest.param(4, marks=pytest.mark.slow)])  # a second history: the full tier
def test_the_timeline_equals_its_queries_evaluated_in_full_after_every_step(store_server: str, seed: int) -> None:
    server = store_server
    history = History(seed)
    for step in range(14):
        send(server, history.next_post())
        settle(server)
        rng = random.Random(seed * 100 + step)
        variants = [{"robot": f"{EX}robot/{rng.choice(ROBOTS)}"}, {"human": f"{EX}human/{rng.choice(HUMANS)}"}]
        if step % 3 == 2:
            variants.append({**variants[0], "since": "2026-03-10T09:20:00Z", "until": "2026-03-10T09:40:00Z"})
        copy = embedded_copy(server)
        for params in variants:
            rows = timeline(server, params, page=7)
            told = Counter((str(row["kind"]), str(row["iri"]), str(row["time"])) for row in rows)
            assert told == evaluated_events(copy, params) + listed_findings(server, params), (step, params)
            instants = [moment(str(row["time"])) for row in rows]
            assert instants == sorted(instants), (step, params, "out of time order")


@pytest.mark.slow  # a long history, then the timeline evaluated in full after each step
def test_the_timeline_of_one_robot_with_a_long_history_equals_its_queries(store_server: str) -> None:
    """One robot and one person for a long time, then late links, re-publishes and a clearing."""
    server = store_server
    history = History(12, robots=("ari",), humans=("maria",))
    for _ in range(3):
        send(server, history.backlog(60))
    steps = [history.next_post() for _ in range(5)] + [None, history.next_post()]
    for step, post in enumerate(steps):
        send(server, post)
        settle(server)
        copy = embedded_copy(server)
        variants = [{"robot": f"{EX}robot/ari"}, {"human": f"{EX}human/maria", "since": "2026-03-10T09:20:00Z"}]
        for params in variants:
            rows = timeline(server, params, page=50)
            told = Counter((str(row["kind"]), str(row["iri"]), str(row["time"])) for row in rows)
            assert told == evaluated_events(copy, params) + listed_findings(server, params), (step, params)
            if step == 0 and "since" not in params:
                assert len(rows) > 180 * 3  # the long history is there: several events an interaction


def test_message_speakers_are_the_conversations_reports(store_server: str) -> None:
    """Who spoke a message is decided once, by the conversations report's `speaker`: the timeline's sentences and
    the explanations must say the same after every step (late senders and re-publishes included). A message's
    time is its activity's: the graph places it at the time the report gives it."""
    server = store_server
    history = History(2)
    speakers: set[str] = set()
    for _ in range(8):
        send(server, history.next_post())
        settle(server)
        speakers |= same_speakers(server)
    assert speakers == {"human", "robot", "unidentified"}  # the history reached each


def same_speakers(server: str) -> set[str]:
    """Each message's sentence tells the speaker the conversations report gives it; the speakers seen."""
    speakers: set[str] = set()
    for robot in ROBOTS:
        iri = f"{EX}robot/{robot}"
        said = {row["iri"]: str(row["sentence"]) for row in timeline(server, {"robot": iri, "kind": "message"}, 50)}
        report = httpx.get(f"{server}/reports/conversations", params={"robot": iri, "limit": 1000}).json()["rows"]
        assert {row["message"] for row in report} == set(said)
        for row in report:
            sentence, name = said[row["message"]], row["robotName"] or robot
            speakers.add(row["speaker"])
            if row["speaker"] == "robot":
                assert sentence.startswith(f"{name} said “") and "(heard by" not in sentence, (row, sentence)
            elif row["speaker"] == "human":
                human = row["humanName"] or str(row["human"]).rsplit("/", 1)[-1]  # nameless: the IRI's end
                assert sentence.startswith(f"{human} said “") and sentence.endswith(f"(heard by {name})")
            else:
                assert sentence.endswith(f"(heard by {name})") and not sentence.startswith(f"{name} said"), sentence
            assert explained_as_said(server, str(row["message"])) == (row["speaker"] == "robot"), row
        drawn = httpx.get(f"{server}/graph", params={"robot": iri, "limit": 5000}, timeout=60).json()["nodes"]
        times = {node["id"]: node.get("time") for node in drawn}
        for row in report:
            assert times.get(row["message"]) == row["time"], (row, times.get(row["message"]))
    return speakers


def explained_as_said(server: str, message: str) -> bool:
    """Whether the explanation of `message` has the robot saying it (rather than hearing it)."""
    story = httpx.get(f"{server}/explain", params={"iri": message}, timeout=60).json()
    said = any(message == told["iri"] for step in story["steps"] for told in step["said"])
    heard = any(message == told["iri"] for step in story["steps"] for told in step["heard"])
    assert said != heard, story  # told once, one way
    return said
