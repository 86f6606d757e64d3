"""The audit rules through the API: every shipped rule finds what it is built for in a log the PyPI client made,
and nothing in the demo's clean parts; a late post that resolves a finding removes it; a rule added as a file is
listed, evaluated and kept with no code change; filters, paging, CSV, errors and the live stream."""

from __future__ import annotations

import shutil
import time
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import httpx
import pytest
from rdflib import Literal
from rdflib.namespace import PROV, XSD
from semantic_log_generator import ActivityKind

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.examples.emotion_mirror.driver import play
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from segb_server.examples.emotion_mirror.script import default_script
from tests.conftest import make_settings
from tests.support.in_process import InProcess, Server, http, publisher_for
from tests.support.live_server import LiveServer
from tests.support.rule_scenarios import troubled
from tests.support.scenarios import at
from tests.support.settle import settle

SHIPPED = PACKAGE_ROOT / "rules"
ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
TIAGO = "https://example.org/segb/robots/tiago/v1/robot_tiago"
MIRROR = "https://example.org/segb/robots/mirror/v1/robot_mirror"


def all_findings(server: Server, **params: str) -> list[dict[str, object]]:
    found: list[dict[str, object]] = []
    after = None
    while True:
        answer = http(server, "GET", "/findings", params={**params, "limit": 5, **({"after": after} if after else {})})
        assert answer.status_code == 200, answer.text
        body = answer.json()
        found += body["findings"]
        if not body["has_more"]:
            return found
        after = body["next"]


def by_rule(findings: list[dict[str, object]]) -> dict[str, set[str]]:
    grouped: dict[str, set[str]] = {}
    for found in findings:
        grouped.setdefault(str(found["rule"]), set()).add(str(found["focus"]))
    return grouped


@pytest.fixture
def api() -> Iterator[httpx.Client]:
    with InProcess(create_app(make_settings())) as served:
        yield served.client


@pytest.fixture
def live_api_url() -> Iterator[str]:
    """Over real HTTP, for reading the stream with a time limit."""
    with LiveServer(create_app(make_settings())) as live:
        yield live.url


def test_every_shipped_rule_finds_what_it_is_built_for_in_a_log_the_client_made(api: httpx.Client) -> None:
    scenario, expected = troubled()
    scenario.publish_all(api)
    found = all_findings(api)
    assert by_rule(found) == expected
    assert set(expected) == {rule.stem for rule in SHIPPED.iterdir() if rule.suffix in (".rq", ".ttl")}
    listed = {rule["id"]: rule for rule in api.get("/rules").json()["rules"]}
    assert {rule_id: rule["findings"] for rule_id, rule in listed.items()} == {k: len(v) for k, v in expected.items()}
    late = next(f for f in found if f["rule"] == "late-answer")
    assert late["robot"] == ARI and late["human"].endswith("human_maria") and late["values"]["seconds"] == 14
    assert late["message"] == "ARI answered Maria after 14 s: “turn 3”"
    assert next(f for f in found if f["rule"] == "time-not-datetime")["values"]["value"] == "ten past nine"


def test_the_demo_is_clean_but_for_what_it_shows_on_purpose(tmp_path: Path) -> None:
    """The demo's findings are its designed cases only: every reply is the mission's fallback (no model runs in
    the demo), and Carlos looked angry (0.88). Every other rule, the data-quality ones among them, finds nothing:
    TIAGo overheard what Maria said to ARI, and ARI answered it, so it is no unanswered message."""
    with InProcess(create_app(make_settings(), demo=True)) as live:
        settle(live.client)
        found = all_findings(live.client)
    grouped = by_rule(found)
    assert set(grouped) == {"reply-without-model", "strong-negative-emotion"}
    assert len(grouped["reply-without-model"]) == 5  # ARI's four replies and TIAGo's one
    (anger,) = [f for f in found if f["rule"] == "strong-negative-emotion"]
    assert anger["robot"] == TIAGO and anger["values"]["category"] == "anger" and anger["values"]["intensity"] == 0.88


# Each reply with the human whose message it answers (derived from), and their name.
ANSWERED = """SELECT ?reply ?human ?name WHERE {
  ?reply <http://www.w3.org/ns/prov#wasDerivedFrom>/<http://schema.org/sender> ?human .
  ?human <http://xmlns.com/foaf/0.1/firstName> ?name }"""


def test_a_reply_without_the_model_names_the_human_it_answers() -> None:
    """What `segb serve --demo` shows once the example robot has run: every reply of ARI, TIAGo and the emotion
    mirror is the fallback, and each finding names the human whose message the reply answers, in its `human`
    and in its sentence."""
    with InProcess(create_app(make_settings(), demo=True)) as live:
        settle(live.client)
        mission = EmotionMirrorMission.start(
            RobotConfig(), human_id="maria", human_name="Maria",
            publish=lambda logger: logger.publish(publisher_for(live.client, "mirror")),
        )  # fmt: skip
        assert list(play(mission, default_script()))
        settle(live.client)
        found = all_findings(live.client, rule="reply-without-model")
        answer = http(live.client, "POST", "/sparql", params={"format": "json"}, content=ANSWERED,
                      headers={"Content-Type": "application/sparql-query"})  # fmt: skip
    assert answer.status_code == 200, answer.text
    answered = {row["reply"]["value"]: row for row in answer.json()["results"]["bindings"]}
    assert len(found) == 9  # ARI's four replies, TIAGo's one, the mirror's four
    assert {f["robot"] for f in found} == {ARI, TIAGO, MIRROR}
    for finding in found:
        human = answered[str(finding["focus"])]
        assert finding["human"] == human["human"]["value"]
        assert f" to {human['name']['value']}: “" in str(finding["message"])
    assert {answered[str(f["focus"])]["name"]["value"] for f in found} == {"Maria", "Carlos"}


def test_a_reply_written_by_the_model_is_no_finding(api: httpx.Client) -> None:
    """The emotion mirror with its model answering (the replier says "ollama"): replies credit the model."""
    publisher = publisher_for(api, "mirror")
    mission = EmotionMirrorMission.start(
        RobotConfig(), human_id="maria", human_name="Maria", replier=lambda text: (f"Oh! {text}", "ollama"),
        publish=lambda logger: logger.publish(publisher),
    )  # fmt: skip
    mission.on_face_expression("happy", at(0))
    mission.respond(mission.on_user_utterance("I passed!", at(1)), at(2.5))
    settle(api)
    assert all_findings(api) == []


def test_a_late_post_that_resolves_a_finding_removes_it(api: httpx.Client) -> None:
    """The emotion mirror publishes after every event: Maria's message is unanswered until the reply's post, and
    an activity's missing start time until a later post gives it."""
    publisher = publisher_for(api, "mirror")
    mission = EmotionMirrorMission.start(
        RobotConfig(), human_id="maria", human_name="Maria", publish=lambda logger: logger.publish(publisher)
    )
    exchange = mission.on_user_utterance("Are you there?", at(0))
    settle(api)
    assert by_rule(all_findings(api)) == {"unanswered-message": {str(exchange.heard)}}
    mission.respond(exchange, at(1.5))
    settle(api)
    assert "unanswered-message" not in by_rule(all_findings(api))
    logger = mission.logger
    untimed = logger.log_activity(activity_id="plan", activity_kind=ActivityKind.DECISION)
    logger.publish(publisher)
    settle(api)
    assert by_rule(all_findings(api, rule="activity-without-start")) == {"activity-without-start": {str(untimed)}}
    logger.graph.add((untimed, PROV.startedAtTime, Literal((at(3)).isoformat(), datatype=XSD.dateTime)))
    logger.publish(publisher)
    settle(api)
    assert all_findings(api, rule="activity-without-start") == []


def test_a_finding_about_a_message_names_the_robot_that_logged_it_never_its_sender(api: httpx.Client) -> None:
    """A person's message in the PyPI client's shape (`schema:sender` and `prov:wasAttributedTo` her) without its
    text: the finding's robot is the one that performed the activity that generated the message, not her."""
    robot, person = "https://example.org/trap/robot", "https://example.org/people/zoe"
    turtle = f"""
        @prefix schema: <http://schema.org/> . @prefix prov: <http://www.w3.org/ns/prov#> .
        @prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> . @prefix oro: <http://kb.openrobots.org#> .
        <{robot}> a oro:Robot .
        <{person}> a oro:Human .
        <https://example.org/trap/listen> a segb:LoggedActivity, oro:ListeningEvent ; segb:wasPerformedBy <{robot}> ;
            prov:startedAtTime "2026-05-02T10:00:00Z"^^<http://www.w3.org/2001/XMLSchema#dateTime> .
        <https://example.org/trap/heard> a schema:Message ; schema:sender <{person}> ; prov:wasAttributedTo <{person}> ;
            prov:wasGeneratedBy <https://example.org/trap/listen> .
    """
    assert publisher_for(api, "trap").publish_turtle(turtle)["triples_new"] > 0
    settle(api)
    mute = [f for f in all_findings(api, rule="message-without-text") if f["focus"] == "https://example.org/trap/heard"]
    assert len(mute) == 1 and mute[0]["robot"] == robot, mute
    assert all_findings(api, robot=person) == []
    assert [f["focus"] for f in all_findings(api, robot=robot)] == ["https://example.org/trap/heard"]


def test_the_answer_delay_and_the_intensity_threshold_are_the_rules_own_defaults(api: httpx.Client) -> None:
    publisher = publisher_for(api, "mirror")
    mission = EmotionMirrorMission.start(
        RobotConfig(), human_id="maria", human_name="Maria", publish=lambda logger: logger.publish(publisher)
    )
    mission.on_face_expression("sad", at(0), confidence=0.74)  # just under 0.75: no finding
    mission.respond(mission.on_user_utterance("Slow", at(1)), at(1) + timedelta(seconds=9.5))  # under 10 s
    mission.on_face_expression("angry", at(20), confidence=0.75)
    late = mission.on_user_utterance("Slower", at(21))
    mission.respond(late, at(31))  # 10 s: a finding
    settle(api)
    grouped = by_rule(all_findings(api))
    assert grouped["late-answer"] == {str(late.heard)}
    assert len(grouped["strong-negative-emotion"]) == 1
    rules = {rule["id"]: rule for rule in api.get("/rules").json()["rules"]}
    assert {p["name"]: p["default"] for p in rules["late-answer"]["parameters"]}["delay"] == "10"
    assert {p["name"]: p["default"] for p in rules["strong-negative-emotion"]["parameters"]}["threshold"] == "0.75"


def test_findings_filter_page_and_download(api: httpx.Client) -> None:
    scenario, expected = troubled()
    scenario.publish_all(api)
    everything = all_findings(api)
    assert len(everything) == sum(len(nodes) for nodes in expected.values())
    violations = all_findings(api, severity="violation")
    assert {f["rule"] for f in violations} == {"time-not-datetime", "emotion-out-of-range", "message-without-text"}
    answer = api.get("/findings", params={"severity": "violation", "limit": 1}).json()
    assert answer["counts"]["by_severity"]["violation"] == 3 and answer["has_more"]
    one = all_findings(api, rule="late-answer")
    assert [f["rule"] for f in one] == ["late-answer"]
    window = all_findings(api, since="2026-03-10T09:00:30Z", until="2026-03-10T09:01:10Z")
    assert {f["rule"] for f in window} == {"late-answer", "reply-without-model"}  # shapes' nodes have no time there
    assert all_findings(api, robot="https://example.org/segb/robots/nobody") == []
    csv = api.get("/findings", params={"format": "csv", "rule": "late-answer"})
    assert csv.headers["content-type"].startswith("text/csv")
    assert csv.text.splitlines()[0] == "time,rule,severity,robot,human,focus,message,values"
    assert "ARI answered Maria after 14 s" in csv.text


@pytest.mark.parametrize(
    ("params", "named"),
    [
        ({"rule": "no-such-rule"}, None),
        ({"severity": "fatal"}, "severity"),
        ({"since": "yesterday"}, "since"),
        ({"robot": "not an iri"}, "robot"),
        ({"limit": "0"}, "limit"),
        ({"after": "nonsense"}, "after"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_a_bad_filter_is_refused_by_name(api: str, params: dict[str, str], named: str | None) -> None:
    answer = api.get("/findings", params=params)
    if named is None:
        assert answer.status_code == 404 and "no-such-rule" in answer.json()["detail"]
    else:
        assert answer.status_code == 422 and named in answer.text


def test_the_stream_announces_new_findings(live_api_url: str) -> None:
    api = live_api_url
    with httpx.stream("GET", f"{api}/findings/stream", timeout=20) as stream:
        lines = stream.iter_lines()
        assert next(lines).startswith("retry:")
        scenario, _ = troubled()
        scenario.publish_all(api)
        deadline = time.monotonic() + 10
        for line in lines:
            if line.startswith("data:"):
                assert '"rules"' in line
                break
            assert time.monotonic() < deadline
    last = httpx.get(f"{api}/findings").json()["last_event_id"]
    assert last != "0.0"


NEW_SPARQL_RULE = """# id: silent-robot
# title: Robot with no name
# severity: violation
# description: A robot the log never names.
# key: ?focus
# param robot: iri — only this robot
PREFIX schema: <http://schema.org/>
PREFIX oro: <http://kb.openrobots.org#>
SELECT ?time ?focus ?robot ?message WHERE {
  ?focus a oro:Robot .
  BIND (?focus AS ?robot)
  FILTER (!BOUND(?param_robot) || ?robot = ?param_robot)
  FILTER NOT EXISTS { ?focus schema:name ?name }
  BIND ("This robot has no name" AS ?message)
}
ORDER BY ?time ?focus
"""
NEW_SHAPE_RULE = """# id: state-without-location
# title: State without a location
# severity: info
# description: A robot state that says nowhere where the robot was.
@prefix sh: <http://www.w3.org/ns/shacl#> .
@prefix prov: <http://www.w3.org/ns/prov#> .
<urn:example:state-shape> a sh:NodeShape ;
    sh:targetSubjectsOf prov:generatedAtTime ;
    sh:property [ sh:path prov:atLocation ; sh:minCount 1 ; sh:message "No location" ] .
"""


def rules_with_two_more(folder: Path) -> Path:
    shutil.copytree(SHIPPED, folder)
    (folder / "silent-robot.rq").write_text(NEW_SPARQL_RULE, encoding="utf-8")
    (folder / "state-without-location.ttl").write_text(NEW_SHAPE_RULE, encoding="utf-8")
    return folder


def test_a_rule_added_as_a_file_is_listed_evaluated_and_kept(tmp_path: Path) -> None:
    rules = rules_with_two_more(tmp_path / "rules")
    with InProcess(create_app(make_settings(rules_dir=rules))) as live:
        listed = {rule["id"]: rule for rule in live.get("/rules").json()["rules"]}
        assert listed["silent-robot"]["severity"] == "violation" and listed["silent-robot"]["kind"] == "sparql"
        assert listed["state-without-location"]["kind"] == "shacl"
        nameless = "<https://example.org/robots/r2d2> a <http://kb.openrobots.org#Robot> ."
        state = (
            "<https://example.org/robots/r2d2/state_1> <http://www.w3.org/ns/prov#generatedAtTime> "
            '"2026-03-10T09:00:00Z"^^<http://www.w3.org/2001/XMLSchema#dateTime> ; '
            "<http://www.w3.org/ns/prov#wasAttributedTo> <https://example.org/robots/r2d2> ; a <urn:x:State> ."
        )
        posted = live.post("/ttl", content=f"{nameless}\n{state}", headers={"Content-Type": "text/turtle"})
        assert posted.status_code == 201
        settle(live.client)
        body = live.get("/findings", params={"rule": ["silent-robot", "state-without-location"]}).json()
        assert {(f["rule"], f["focus"]) for f in body["findings"]} == {
            ("silent-robot", "https://example.org/robots/r2d2"),
            ("state-without-location", "https://example.org/robots/r2d2/state_1"),
        }
        assert body["served_from"] == {"silent-robot": "rows", "state-without-location": "rows"}
        named = '<https://example.org/robots/r2d2> <http://schema.org/name> "R2" .'
        assert live.post("/ttl", content=named, headers={"Content-Type": "text/turtle"}).status_code == 201
        settle(live.client)
        assert all_findings(live.client, rule="silent-robot") == []


def test_a_rule_file_that_is_not_a_rule_stops_the_server_naming_it(tmp_path: Path) -> None:
    from segb_server.backend.services.rules.catalog import RuleCatalog, RuleError

    folder = tmp_path / "rules"
    folder.mkdir()
    (folder / "broken.rq").write_text("# id: broken\n# severity: fatal\nSELECT * WHERE { ?s ?p ?o }\n")
    with pytest.raises(RuleError, match=r"broken\.rq.*severity"):
        RuleCatalog(folder)
    (folder / "broken.rq").write_text("# id: broken\n# severity: info\nSELECT ?focus WHERE { ?focus ?p ?o }\n")
    with pytest.raises(RuleError, match=r"must project \?message"):
        RuleCatalog(folder)


def test_validate_answers_the_rules_findings_for_the_posted_log(api: httpx.Client) -> None:
    scenario, expected = troubled()
    scenario.run_steps()
    (turtle,) = scenario.published_turtle()
    body = api.post("/ttl/validate", json={"ttl_content": turtle}).json()
    assert by_rule(body["findings"]) == expected
    assert body["rules_ok"] is False
    lines = turtle.splitlines()
    for found in body["findings"]:
        assert found["line"] is not None
        local = str(found["focus"]).rsplit("/", 1)[-1]
        assert local in lines[found["line"] - 1], found
