"""GET /timeline over real HTTP on both stores: the incident's timelines (two robots, two humans, published with
the PyPI client step by step, a late link, re-publishes) list every event once, in time order, each with the
sentence the log supports; filters, keyset paging, CSV, the HTML file, refusals by name, and the live stream."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterator

import httpx
import pytest
from semantic_log_generator import SEGBPublisher

from segb_server.backend.api.app import create_app
from segb_server.backend.services.timeline.findings_source import told
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import STORE_KINDS, make_settings, virtuoso_store
from tests.support.investigation import incident
from tests.support.live_server import LiveServer
from tests.support.scenarios import Scenario, publish_message
from tests.support.settle import settle
from tests.support.streams import first_event

DAY_BEFORE = "2026-03-09T09:00:00Z"

# What each timeline must say, event by event: (time, kind, sentence). Built by hand from how the incident is
# logged (tests/support/investigation.py): a model only beside the activity that used it, a robot's own emotion
# expressed and a human's read, the unnamed speaker named once the log names him.
ARI = [
    (DAY_BEFORE, "activity", "ARI: Train emotion CNN"),
    ("2026-03-10T09:00:00Z", "shared-event", "Shared event about Maria"),
    ("2026-03-10T09:00:00Z", "perception", "ARI detected Maria"),
    ("2026-03-10T09:00:05Z", "shared-event", "Shared event about Maria: “I passed my driving test today!”"),
    ("2026-03-10T09:00:05Z", "listening", "ARI listened"),
    ("2026-03-10T09:00:05Z", "message", "Maria said “I passed my driving test today!” (heard by ARI)"),
    ("2026-03-10T09:00:06Z", "perception", "ARI ran emotion recognition about Maria"),
    ("2026-03-10T09:00:06Z", "model", "ARI used Emotion Big6 CNN 1.0 (emotion recognition)"),
    ("2026-03-10T09:00:06Z", "emotion", "ARI read happiness 0.9 on Maria (confidence 0.95)"),
    ("2026-03-10T09:00:08Z", "response", "ARI responded"),
    ("2026-03-10T09:00:08Z", "message", "ARI said “Congratulations, Maria!”"),
    ("2026-03-10T09:00:10Z", "state", "ARI's state: at room_a, battery_level 82 %, mission_phase greeting"),
    ("2026-03-10T09:00:15Z", "activity", "ARI logged an emotion annotation"),
    ("2026-03-10T09:00:15Z", "emotion", "ARI expressed happiness 0.6"),
    ("2026-03-10T09:00:20Z", "listening", "ARI listened"),
    ("2026-03-10T09:00:20Z", "message", "Maria said “Thanks!” (heard by ARI)"),
    ("2026-03-10T09:00:30Z", "shared-event", "Shared event about Maria"),
    ("2026-03-10T09:00:30Z", "perception", "ARI detected Maria (Watch the door)"),
    ("2026-03-10T09:00:30Z", "observation", "ARI observed “Maria left the lobby”"),
]
TIAGO = [
    ("2026-03-10T09:00:07Z", "shared-event", "Shared event about Juan: “Where is the pharmacy?”"),
    ("2026-03-10T09:00:07Z", "listening", "TIAGo listened"),
    ("2026-03-10T09:00:07Z", "message", "Juan said “Where is the pharmacy?” (heard by TIAGo)"),
    ("2026-03-10T09:00:09Z", "response", "TIAGo responded"),
    ("2026-03-10T09:00:09Z", "model", "TIAGo used Llama 3 3.1 (response)"),
    ("2026-03-10T09:00:09Z", "message", "TIAGo said “Second floor, Juan.”"),
    ("2026-03-10T09:00:12Z", "perception", "TIAGo ran emotion recognition"),
    ("2026-03-10T09:00:12Z", "emotion", "TIAGo read anger 0.8 on Juan"),
    ("2026-03-10T09:00:18Z", "state", "TIAGo's state: arm_calibrated true, battery_level 41.5 %"),
    ("2026-03-10T09:00:25Z", "listening", "TIAGo listened (Listen)"),
    ("2026-03-10T09:00:25Z", "message", "Juan said “Is anyone there?” (heard by TIAGo)"),
    ("2026-03-10T09:00:26Z", "decision", "TIAGo decided Guide Juan to the pharmacy"),
]
# A human's timeline: what involved them, whichever robot logged it; no robot's states.
MARIA = [event for event in ARI if event[1] != "state" and event[0] != DAY_BEFORE and "expressed" not in event[2]]
MARIA.remove(("2026-03-10T09:00:15Z", "activity", "ARI logged an emotion annotation"))
JUAN = [event for event in TIAGO if event[1] != "state"]
# The audit rules' findings on ARI's timeline: each after the events of its instant (tests/support/investigation.py
# logs a reply made without the dialogue model and a "Thanks!" nobody answers).
ARI_FINDINGS = [
    (
        "2026-03-10T09:00:08Z",
        "finding",
        "Note: Reply without the dialogue model — ARI replied without using any model to Maria: "
        "“Congratulations, Maria!”",
    ),
    ("2026-03-10T09:00:20Z", "finding", "Warning: Message never answered — ARI never answered Maria: “Thanks!”"),
]
ARI_ALL = sorted(ARI + ARI_FINDINGS, key=lambda event: event[0])  # stable: a finding after its instant's events
UNNAMED = "An unidentified speaker said “Is anyone there?” (heard by TIAGo)"


class Incident:
    def __init__(self, scenario: Scenario, url: str, before_the_late_link: list[tuple[str, str, str]]) -> None:
        self.scenario = scenario
        self.url = url
        self.before_the_late_link = before_the_late_link

    def iri(self, name: str) -> str:
        return str(self.scenario.iris[name])

    def get(self, path: str = "/timeline", **params: object) -> httpx.Response:
        return httpx.get(f"{self.url}{path}", params=params, timeout=60)  # type: ignore[arg-type]

    def rows(self, **params: object) -> list[dict[str, object]]:
        answer = self.get(**params)
        assert answer.status_code == 200, answer.text
        return answer.json()["rows"]

    def ari_with_findings(self) -> list[tuple[str, str, str]]:
        """ARI's events with the findings `GET /findings` lists for ARI, told as the timeline tells them, each
        after the events of its instant: what paging, CSV and the HTML file must hold, on either store."""
        listed = self.get("/findings", robot=self.iri("ari"), limit=500).json()["findings"]
        findings = [(str(f["time"]), "finding", told(f).sentence) for f in listed if f["time"]]
        return sorted(ARI + findings, key=lambda event: event[0])

    def told(self, **params: object) -> list[tuple[str, str, str]]:
        """The events robots logged, (time, kind, sentence); the audit rules' findings, which the timeline
        shows among them, have a test of their own."""
        rows = [row for row in self.rows(**params) if row["kind"] != "finding"]
        return [(str(row["time"]), str(row["kind"]), str(row["sentence"])) for row in rows]


@pytest.fixture(scope="module", params=STORE_KINDS)
def published(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Incident]:
    if request.param == "virtuoso":
        store: Store = virtuoso_store(request.getfixturevalue("virtuoso"))
    else:
        store = OxigraphStore("http://amor-segb/events", tmp_path_factory.mktemp("timeline") / "oxigraph")
    scenario = incident()
    seen_before: list[tuple[str, str, str]] = []
    with LiveServer(create_app(make_settings(store=request.param), store=store)) as live:
        publishers = {name: SEGBPublisher(base_url=live.url, default_user=name) for name in scenario.loggers}
        steps = iter(range(len(scenario.steps)))

        def publish(robot: str) -> None:  # the whole accumulated graph after every step, as a robot does
            scenario.loggers[robot].publish(publishers[robot])
            if next(steps) == len(scenario.steps) - 2:  # the step before TIAGo learns who spoke
                settle(live.url)
                answer = httpx.get(f"{live.url}/timeline", params={"robot": str(scenario.iris["tiago"])}).json()
                seen_before.extend((row["time"], row["kind"], row["sentence"]) for row in answer["rows"])

        scenario.run_steps(publish)
        for name, robot in scenario.loggers.items():  # and everything once more: a re-publish changes nothing
            robot.publish(publishers[name])
        settle(live.url)
        yield Incident(scenario, live.url, seen_before)
    if request.param == "virtuoso":
        store.clear()
    store.close()


def test_each_timeline_lists_every_event_once_in_time_order_with_honest_sentences(published: Incident) -> None:
    assert published.told(robot=published.iri("ari")) == ARI
    assert published.told(robot=published.iri("tiago")) == TIAGO
    assert published.told(human=published.iri("maria")) == MARIA
    assert published.told(human=published.iri("juan")) == JUAN
    ids = [row["id"] for row in published.rows(robot=published.iri("ari"))]
    assert len(ids) == len(set(ids))


@pytest.mark.parametrize(("whose", "name"), [("robot", "ari"), ("robot", "tiago"), ("human", "maria")])
def test_the_findings_of_the_window_are_on_its_timeline_as_the_findings_page_lists_them(
    published: Incident, whose: str, name: str
) -> None:
    window = {whose: published.iri(name)}
    listed = published.get("/findings", **window, limit=500).json()["findings"]
    timed = [found for found in listed if found["time"]]
    assert timed, "the incident breaks some rules"
    on_timeline = [row for row in published.rows(**window) if row["kind"] == "finding"]
    assert [(row["time"], row["iri"]) for row in on_timeline] == [(f["time"], f["focus"]) for f in timed]
    for row, found in zip(on_timeline, timed, strict=True):
        assert found["title"] in row["sentence"] and (found["message"] or "") in row["sentence"]
        assert row["explain"] == "/explain?" + str(httpx.QueryParams({"iri": found["focus"]}))
    everything = published.rows(**window)
    assert [row["time"] for row in everything] == sorted(row["time"] for row in everything)  # merged in time order


def test_a_late_sender_names_the_speaker_the_timeline_could_not_name_before(published: Incident) -> None:
    at_25 = [event for event in published.before_the_late_link if event[0] == "2026-03-10T09:00:25Z"]
    assert at_25 == [
        ("2026-03-10T09:00:25Z", "listening", "TIAGo listened (Listen)"),
        ("2026-03-10T09:00:25Z", "message", UNNAMED),
    ]
    now = published.told(robot=published.iri("tiago"), since="2026-03-10T09:00:25Z", until="2026-03-10T09:00:25Z")
    assert now == [at_25[0], ("2026-03-10T09:00:25Z", "message", "Juan said “Is anyone there?” (heard by TIAGo)")]


def test_rows_name_what_they_are_about_and_link_to_its_explanation_and_graph(published: Incident) -> None:
    rows = published.rows(robot=published.iri("tiago"), kind="message")
    row = next(row for row in rows if row["iri"] == published.iri("tiago_1"))
    assert (row["robot"], row["humans"]) == (published.iri("tiago"), [published.iri("juan")])
    assert row["explain"] == "/explain?" + str(httpx.QueryParams({"iri": published.iri("tiago_1")}))
    assert row["graph"] == "/kg-graph?" + str(httpx.QueryParams({"focus": published.iri("tiago_1")}))
    story = published.get("/explain", iri=row["iri"]).json()  # the API's own explanation of the same message
    assert any("Second floor, Juan." in step["sentence"] for step in story["steps"])


def test_a_model_is_named_only_beside_the_activity_that_used_it(published: Incident) -> None:
    for robot in ("ari", "tiago"):
        for row in published.rows(robot=published.iri(robot)):
            names_a_model = "Llama" in str(row["sentence"]) or "CNN 1.0" in str(row["sentence"])
            assert names_a_model == (row["kind"] == "model"), row
    models = published.rows(robot=published.iri("tiago"), kind="model")
    assert [row["iri"] for row in models] == [published.iri("reply_juan_1")]


def test_kinds_and_the_window_filter_the_events(published: Incident) -> None:
    ari = published.iri("ari")
    assert {kind for _, kind, _ in published.told(robot=ari, kind="message")} == {"message"}
    both = published.told(robot=ari, kind=["emotion", "model"])
    assert both == published.told(robot=ari, kind="emotion,model")
    assert both == [event for event in ARI if event[1] in ("emotion", "model")]
    window = published.told(robot=ari, since="2026-03-10T09:00:06Z", until="2026-03-10T10:00:08+01:00")
    assert window == [event for event in ARI if "2026-03-10T09:00:06Z" <= event[0] <= "2026-03-10T09:00:08Z"]
    with_maria = published.told(robot=published.iri("tiago"), human=published.iri("maria"))
    assert with_maria == []  # TIAGo never met Maria
    answer = published.get(robot=ari, kind="state").json()
    assert answer["kinds"] == ["state"] and set(answer["served_from"].values()) == {"rows"}


@pytest.mark.parametrize("limit", [1, 2, 5])
def test_pages_through_next_give_every_event_once_in_order(published: Incident, limit: int) -> None:
    told: list[tuple[str, str, str]] = []
    params: dict[str, object] = {"robot": published.iri("ari"), "limit": limit}
    while True:
        answer = published.get(**params).json()
        assert len(answer["rows"]) <= limit
        told += [(row["time"], row["kind"], row["sentence"]) for row in answer["rows"]]
        if not answer["has_more"]:
            assert answer["next"] is None
            break
        params["after"] = answer["next"]
    assert told == published.ari_with_findings()  # the findings' source paged with the kinds' sources


def test_a_cursor_serves_only_the_filters_it_was_made_for(published: Incident) -> None:
    first = published.get(robot=published.iri("ari"), limit=3).json()
    elsewhere = published.get(robot=published.iri("tiago"), limit=3, after=first["next"])
    assert (elsewhere.status_code, elsewhere.json()["parameter"]) == (422, "after")
    assert "other filters" in elsewhere.json()["detail"]
    for garbage in ("zzz", "eyJ2IjoxfQ", "e30"):
        answer = published.get(robot=published.iri("ari"), after=garbage)
        assert (answer.status_code, answer.json()["parameter"]) == (422, "after")


@pytest.mark.parametrize(
    ("params", "parameter"),
    [
        ({}, "robot"),
        ({"robot": "not an iri"}, "robot"),
        ({"human": "ftp://x"}, "human"),
        ({"robot": "https://x.org/r", "since": "yesterday"}, "since"),
        ({"robot": "https://x.org/r", "since": "2026-03-10T09:00:00"}, "since"),  # no zone
        ({"robot": "https://x.org/r", "since": "2026-03-10T10:00:00Z", "until": "2026-03-10T09:00:00Z"}, "until"),
        ({"robot": "https://x.org/r", "kind": "dream"}, "kind"),
    ],
)
def test_a_bad_request_is_refused_naming_the_parameter(published: Incident, params: dict, parameter: str) -> None:  # type: ignore[type-arg]
    answer = published.get(**params)
    assert (answer.status_code, answer.json()["parameter"]) == (422, parameter)


def test_a_page_size_out_of_bounds_is_refused(published: Incident) -> None:
    for limit in (0, 10_001):
        answer = published.get(robot=published.iri("ari"), limit=limit)
        assert answer.status_code == 422 and "limit" in answer.json()["message"]


def test_csv_holds_the_rows_of_the_json(published: Incident) -> None:
    answer = published.get(robot=published.iri("ari"), format="csv")
    assert answer.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(answer.text)))
    assert [(row["time"], row["kind"], row["sentence"]) for row in rows] == published.ari_with_findings()
    assert rows[1]["humans"] == published.iri("maria")
    same = published.rows(robot=published.iri("ari"))
    assert [row["iri"] for row in rows] == [row["iri"] for row in same]


def test_the_html_file_holds_the_window_and_runs_only_its_own_script(published: Incident) -> None:
    answer = published.get(robot=published.iri("ari"), format="html")
    assert answer.headers["content-type"] == "text/html; charset=utf-8"
    html = answer.text
    assert "default-src 'none'; script-src 'sha256-" in html
    data = html.split('<script type="application/json" id="timeline-data">', 1)[1].split("</script>", 1)[0]
    rows = json.loads(data)
    assert [(row["time"], row["kind"], row["sentence"]) for row in rows] == published.ari_with_findings()
    assert all(row["explain"] is None for row in rows)  # no server to explain them: no links


def test_the_stream_sends_a_published_message_as_its_timeline_row(live_api: LiveServer) -> None:
    ari = "https://example.org/segb/robots/ari/v1/robot_ari"
    answer = httpx.get(f"{live_api.url}/timeline", params={"robot": ari}).json()
    message = publish_message(live_api.url, "Where did I leave my keys?")
    event = first_event(
        f"{live_api.url}/timeline/stream?" + str(httpx.QueryParams({"robot": ari, "kind": "message"})),
        {"Last-Event-ID": str(answer["last_event_id"])},
    )
    change = json.loads(event["data"])
    assert (event["event"], change["kind"]) == ("rows", "message")
    assert message in change["keys"]  # with whatever else the post may have changed: their rows, if any, follow
    assert [row["sentence"] for row in change["rows"]] == ["Maria said “Where did I leave my keys?” (heard by ARI)"]
    assert int(event["id"]) > answer["last_event_id"]


@pytest.mark.parametrize("kind", STORE_KINDS)
def test_evaluated_in_full_the_timeline_says_the_same(kind: str, request: pytest.FixtureRequest, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """While a kind's rows are being built (or with KEEP_VIEWS=false), its query answers: the same events, paged
    with the same cursors."""
    store: Store = (
        virtuoso_store(request.getfixturevalue("virtuoso"))
        if kind == "virtuoso"
        else OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    )
    try:
        with LiveServer(create_app(make_settings(store=kind, keep_views=False), store=store)) as live:
            scenario = incident()
            scenario.publish_all(live.url)
            evaluated = Incident(scenario, live.url, [])
            if kind == "virtuoso":
                # Virtuoso 7 answers a filter kept as facets (whether an activity involves a human, whether a robot
                # took part in a shared event) wrongly with its value bound: those wait for the rows (503), the
                # others answer.
                for window in ({"human": evaluated.iri("maria")}, {"robot": evaluated.iri("ari")}):
                    answer = evaluated.get(**window)
                    assert (answer.status_code, answer.json()["error"]) == (503, "view_not_ready"), window
                plain = ("message", "emotion", "state")
                told = evaluated.told(robot=evaluated.iri("tiago"), kind=",".join(plain))
                assert told == [event for event in TIAGO if event[1] in plain]
                return
            assert evaluated.get(robot=evaluated.iri("ari")).json()["served_from"]["message"] == "query"
            assert evaluated.told(robot=evaluated.iri("tiago")) == TIAGO
            assert evaluated.told(human=evaluated.iri("maria")) == MARIA
            assert evaluated.told(human=evaluated.iri("juan")) == JUAN
            told, params = [], {"robot": evaluated.iri("ari"), "limit": 4}
            while True:
                answer = evaluated.get(**params).json()
                told += [(row["time"], row["kind"], row["sentence"]) for row in answer["rows"]]
                if not answer["has_more"]:
                    break
                params["after"] = answer["next"]
            assert told == ARI_ALL
    finally:
        if kind == "virtuoso":
            store.clear()
        store.close()
