"""The six audit reports on the multi-robot, multi-human lobby scenario, on both stores, over HTTP.

Every expected row follows from how `tests.support.scenarios.lobby` is built; the scenario is published
with the real client, cumulatively, into the embedded store and into a real Virtuoso at the same time.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterator

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings, virtuoso_store
from tests.support.in_process import InProcess, publisher_for
from tests.support.scenarios import Scenario, lobby
from tests.support.settle import settle

pytestmark = pytest.mark.virtuoso


class Published:
    def __init__(self, scenario: Scenario, servers: dict[str, InProcess]) -> None:
        self.scenario = scenario
        self.servers = servers

    def iri(self, name: str) -> str:
        return str(self.scenario.iris[name])

    def get(self, store: str, path: str, **params: object) -> httpx.Response:
        return self.servers[store].get(path, params=params)  # type: ignore[arg-type]

    def evidence(self, store: str, report: str) -> str:
        """The report's rows beside its query's own answer from the store, for a failure message."""
        text = (PACKAGE_ROOT / "sparql" / "reports" / f"{report}.rq").read_text()
        evaluated = self.servers[store].post("/sparql", data={"query": text}, headers={"Accept": "text/csv"}).text
        return json.dumps({"rows": self.rows(store, report), "evaluated": evaluated}, indent=1)

    def rows(self, store: str, report: str, **params: object) -> list[dict[str, object]]:
        response = self.get(store, f"/reports/{report}", **params)
        assert response.status_code == 200, response.text
        return response.json()["rows"]


@pytest.fixture(scope="module")
def published(virtuoso, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Published]:  # type: ignore[no-untyped-def]
    stores = {
        "oxigraph": OxigraphStore("http://amor-segb/events", tmp_path_factory.mktemp("reports") / "oxigraph"),
        "virtuoso": virtuoso_store(virtuoso),
    }
    servers = {kind: InProcess(create_app(make_settings(), store=store)) for kind, store in stores.items()}
    for server in servers.values():
        server.__enter__()
    scenario = lobby()
    publishers = {
        (kind, robot): publisher_for(server.client, robot)
        for kind, server in servers.items()
        for robot in scenario.loggers
    }

    def publish_everywhere(robot: str) -> None:
        for kind in servers:  # the whole accumulated graph after every step, as a robot does
            scenario.loggers[robot].publish(publishers[(kind, robot)])

    scenario.run_steps(publish_everywhere)
    for server in servers.values():
        settle(server.client)
    yield Published(scenario, servers)
    for server in servers.values():
        server.__exit__(None, None, None)
    stores["virtuoso"].clear()
    for store in stores.values():
        store.close()


STORES = ["oxigraph", "virtuoso"]


def short(value: object) -> str:
    return str(value).rsplit("/", 1)[-1]


def test_list_names_the_six_reports_with_titles_and_parameters(published: Published) -> None:
    listing = published.get("oxigraph", "/reports").json()["reports"]
    by_name = {report["name"]: report for report in listing}
    assert set(by_name) == {
        "participants", "ml-usage", "emotion-timeline", "extreme-emotions", "conversations", "robot-states"
    }  # fmt: skip
    for report in listing:
        assert report["title"] and report["description"]
        assert {"robot", "human", "since", "until"} <= {p["name"] for p in report["parameters"]}
    threshold = next(p for p in by_name["extreme-emotions"]["parameters"] if p["name"] == "threshold")
    assert threshold["default"] == "0.75"


@pytest.mark.parametrize("store", STORES)
def test_participants_pair_each_human_only_with_the_robot_that_met_them(published: Published, store: str) -> None:
    rows = published.rows(store, "participants")
    pairs = {(short(row["human"]), short(row["robot"])): row for row in rows}
    # Juan's IRI is minted in ARI's namespace, but only TIAGo talked to him.
    assert set(pairs) == {("human_maria", "robot_ari"), ("human_juan", "robot_tiago")}
    maria = pairs[("human_maria", "robot_ari")]
    assert (maria["humanName"], maria["robotName"]) == ("Maria", "ARI")
    # detection, listening, emotion recognition and reply at 09:00:00-08, the second listening at 09:00:20
    assert maria["interactions"] == 5
    assert (maria["firstSeen"], maria["lastSeen"]) == ("2026-03-10T09:00:00Z", "2026-03-10T09:00:20Z")
    juan = pairs[("human_juan", "robot_tiago")]
    assert juan["interactions"] == 3  # listening, reply, and the emotion read without a shared event


@pytest.mark.parametrize("store", STORES)
def test_ml_usage_lists_each_use_with_kind_robot_and_training_lineage(published: Published, store: str) -> None:
    rows = published.rows(store, "ml-usage")
    uses = {(short(row["model"]), short(row["activity"])): row for row in rows}
    assert set(uses) == {("model_emotion_cnn", "activity_emotion_maria_1"), ("model_llm", "activity_reply_juan_1")}
    cnn = uses[("model_emotion_cnn", "activity_emotion_maria_1")]
    assert (cnn["modelName"], cnn["version"], cnn["provider"]) == ("Emotion Big6 CNN", "1.0", "GSI")
    assert (cnn["activityKind"], short(cnn["robot"]), cnn["time"]) == (
        "emotion-recognition",
        "robot_ari",
        "2026-03-10T09:00:06Z",
    )
    assert (cnn["trainingRun"], cnn["dataset"]) == (published.iri("train_run"), published.iri("faces_v1"))
    assert cnn["score"] == pytest.approx(0.91) and cnn["evaluationName"] == "Accuracy"  # what the score measures
    assert cnn["trainingRunName"] == "Train emotion CNN"  # the run by its name, as the page shows it
    llm = uses[("model_llm", "activity_reply_juan_1")]
    assert (llm["activityKind"], short(llm["robot"]), llm["provider"]) == ("response", "robot_tiago", "Meta")
    assert llm["trainingRun"] is None


@pytest.mark.parametrize("store", STORES)
def test_emotion_timeline_keeps_readings_without_shared_event_and_tells_targets_apart(
    published: Published, store: str
) -> None:
    rows = published.rows(store, "emotion-timeline")
    seen = [(row["time"], short(row["target"]), row["targetKind"], row["category"], row["intensity"]) for row in rows]
    assert seen == [
        ("2026-03-10T09:00:06Z", "human_maria", "human", "happiness", pytest.approx(0.9)),
        ("2026-03-10T09:00:12Z", "human_juan", "human", "anger", pytest.approx(0.8)),  # no shared event
        ("2026-03-10T09:00:15Z", "robot_ari", "robot", "happiness", pytest.approx(0.6)),  # expressed by ARI
    ], published.evidence(store, "emotion-timeline")
    assert [row["confidence"] for row in rows] == [pytest.approx(0.95), None, None]
    assert [short(row["robot"]) for row in rows] == ["robot_ari", "robot_tiago", "robot_ari"]
    assert rows[0]["activity"] == published.iri("emotion_maria_1")


@pytest.mark.parametrize("store", STORES)
def test_extreme_emotions_apply_the_threshold(published: Published, store: str) -> None:
    default = published.rows(store, "extreme-emotions")
    assert [short(row["target"]) for row in default] == ["human_maria", "human_juan"], published.evidence(
        store, "extreme-emotions"
    )  # 0.9, 0.8 ≥ 0.75
    strict = published.rows(store, "extreme-emotions", threshold="0.85")
    assert [row["intensity"] for row in strict] == [pytest.approx(0.9)]


@pytest.mark.parametrize("store", STORES)
def test_conversations_attribute_each_message_only_to_its_real_human(published: Published, store: str) -> None:
    rows = published.rows(store, "conversations")
    assert len(rows) == len({row["message"] for row in rows}) == 5  # no message repeated per human
    by_pair: dict[tuple[str, str], list[tuple[str, str, str]]] = {}
    for row in rows:
        key = (short(row["robot"]), short(row["human"]))
        by_pair.setdefault(key, []).append((row["speaker"], row["text"], row["language"]))
    assert by_pair == {
        ("robot_ari", "human_maria"): [
            ("human", "I passed my driving test today!", "en"),
            ("robot", "Congratulations, Maria!", "en"),
            ("human", "Thanks!", "en"),
        ],
        ("robot_tiago", "human_juan"): [
            ("human", "Where is the pharmacy?", "es"),
            ("robot", "Second floor, Juan.", "en"),
        ],
    }
    times = [row["time"] for row in rows if short(row["robot"]) == "robot_ari"]
    assert times == sorted(times)


@pytest.mark.parametrize("store", STORES)
def test_robot_states_include_states_without_location_and_every_property(published: Published, store: str) -> None:
    rows = published.rows(store, "robot-states")
    states: dict[str, dict[str, object]] = {}
    for row in rows:
        state = states.setdefault(short(row["state"]), {"location": row["location"], "time": row["time"]})
        state[row["property"]] = (row["value"], row["unit"])
    assert states == {
        "state_ari_state_1": {
            "location": published.iri("ari").replace("robot_ari", "room_a"),
            "time": "2026-03-10T09:00:10Z",
            "battery_level": (82.0, "PERCENT"),
            "mission_phase": ("greeting", None),
        },
        "state_tiago_state_1": {
            "location": None,
            "time": "2026-03-10T09:00:18Z",
            "battery_level": (41.5, "PERCENT"),
            "arm_calibrated": (True, None),
        },
    }


@pytest.mark.parametrize("store", STORES)
def test_filters_restrict_rows_by_robot_human_and_time(published: Published, store: str) -> None:
    tiago = published.iri("tiago")
    for report in ("participants", "ml-usage", "emotion-timeline", "conversations", "robot-states"):
        rows = published.rows(store, report, robot=tiago)
        assert rows and {row["robot"] for row in rows} == {tiago}, report
    maria = published.iri("maria")
    assert {row["human"] for row in published.rows(store, "conversations", human=maria)} == {maria}
    assert {row["target"] for row in published.rows(store, "emotion-timeline", human=maria)} == {maria}
    window = published.rows(store, "conversations", since="2026-03-10T09:00:06Z", until="2026-03-10T10:00:08+01:00")
    assert [row["text"] for row in window] == ["Congratulations, Maria!", "Where is the pharmacy?"]


def test_same_rows_on_both_stores(published: Published) -> None:
    for report in published.get("oxigraph", "/reports").json()["reports"]:
        embedded = published.get("oxigraph", report["href"]).json()
        virtuoso = published.get("virtuoso", report["href"]).json()
        # Each server's stream counts the batches its own views made; the rows are what must agree.
        assert embedded.pop("last_event_id") > 0 and virtuoso.pop("last_event_id") > 0
        assert embedded == virtuoso, report["name"]


def test_csv_has_the_json_columns_and_rows(published: Published) -> None:
    as_json = published.get("oxigraph", "/reports/conversations").json()
    response = published.servers["oxigraph"].get("/reports/conversations", headers={"Accept": "text/csv"})
    assert response.headers["content-type"].startswith("text/csv")
    table = list(csv.reader(io.StringIO(response.text)))
    assert table[0] == as_json["columns"]
    assert [row[table[0].index("text")] for row in table[1:]] == [row["text"] for row in as_json["rows"]]
    by_format = published.get("oxigraph", "/reports/conversations", format="csv")
    assert by_format.text == response.text


def test_paging_with_limit_offset_and_has_more(published: Published) -> None:
    everything = published.rows("oxigraph", "conversations")
    first = published.get("oxigraph", "/reports/conversations", limit=2).json()
    assert (len(first["rows"]), first["has_more"]) == (2, True)
    rest = published.get("oxigraph", "/reports/conversations", limit=10, offset=2).json()
    assert (first["rows"] + rest["rows"], rest["has_more"]) == (everything, False)


@pytest.mark.parametrize("store", ["oxigraph", "virtuoso"])
def test_paging_by_cursor_returns_every_row_once_in_order(published: Published, store: str) -> None:
    everything = published.rows(store, "conversations")
    pages, after = [], None
    while True:
        body = published.get(store, "/reports/conversations", limit=2, **({"after": after} if after else {})).json()
        assert body["served_from"] == "rows"
        pages += body["rows"]
        if not body["has_more"]:
            break
        after = body["next"]
    assert pages == everything


@pytest.mark.parametrize(
    ("path", "params", "status", "named"),
    [
        ("/reports/nope", {}, 404, "nope"),
        ("/reports/conversations", {"since": "yesterday"}, 422, "since"),
        ("/reports/conversations", {"since": "2026-03-10T09:00:00"}, 422, "since"),
        ("/reports/conversations", {"since": "2026-03-10"}, 422, "needs a time of day and a time zone"),
        ("/reports/conversations", {"robot": "ari"}, 422, "robot"),
        ("/reports/conversations", {"colour": "red"}, 422, "colour"),
        ("/reports/extreme-emotions", {"threshold": "high"}, 422, "threshold"),
        ("/reports/conversations", {"limit": "0"}, 422, "limit"),
        ("/reports/conversations", {"format": "xml"}, 422, "format"),
        ("/reports/conversations", {"after": "nonsense"}, 422, "after"),
        ("/reports/conversations", {"after": '["2", "x"]'}, 422, "after"),
        ("/reports/conversations", {"after": "WyIyIiwgIngiLCAieSJd"}, 422, "after"),  # base64 of ["2", "x", "y"]
        # base64 of ["x", "y", 99999999999999999999999]: past SQLite's integers
        ("/reports/conversations", {"after": "WyJ4IiwgInkiLCA5OTk5OTk5OTk5OTk5OTk5OTk5OTk5OV0"}, 422, "after"),
    ],
)
def test_bad_requests_name_the_problem(published: Published, path: str, params: dict, status: int, named: str) -> None:
    response = published.get("oxigraph", path, **params)
    assert response.status_code == status
    assert named in response.text
    assert set(response.json()) >= {"detail", "error", "status"}


def test_a_filter_value_cannot_inject_sparql(published: Published) -> None:
    hostile = "https://ex.org/a> } UNION { ?s ?p ?o } #"
    response = published.get("oxigraph", "/reports/conversations", robot=hostile)
    assert response.status_code in (200, 422)
    if response.status_code == 200:
        assert response.json()["rows"] == []


def test_reports_follow_every_write_even_when_cached(memory_api: InProcess) -> None:
    """Report pages are served from rows kept current (and cached): a publish or a delete shows once the views
    have caught up, never a stale page after that."""
    scenario = lobby()
    steps = iter(scenario.steps)
    publisher = publisher_for(memory_api.client)

    def conversations() -> list[str]:
        settle(memory_api.client)
        return [row["text"] for row in memory_api.get("/reports/conversations").json()["rows"]]

    for robot, step in steps:
        step()
        scenario.loggers[robot].publish(publisher)
        if step.__name__ == "maria_speaks":
            break
    assert conversations() == ["I passed my driving test today!", "Congratulations, Maria!"]
    assert conversations() == ["I passed my driving test today!", "Congratulations, Maria!"]  # from the cache
    for robot, step in steps:
        step()
        scenario.loggers[robot].publish(publisher)
    assert "Thanks!" in conversations()
    memory_api.post("/ttl/delete_all", json={"user": "admin"})
    assert conversations() == []
