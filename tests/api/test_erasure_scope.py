"""An erasure takes one person and only what concerns them, on a server with authentication and the demo dataset
the real robot client publishes: a robot that links its own resources to someone else's (its "emotions" being
Carlos and TIAGo) erases no one but its own; a class, an IRI the log does not type as a person and a robot are
refused; a dry run counts what would go and writes nothing; after an erasure a re-publish re-attaches nothing to
the erased IRIs; the server log forgets the path a request naming the person was logged as."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import pytest
from semantic_log_generator import SEGBPublisher
from semantic_log_generator.shared_context import HTTPSharedContextResolver

from segb_server.backend.api.app import create_app
from segb_server.backend.api.request_context import logged_path
from segb_server.backend.auth import mint_token
from segb_server.backend.demo import demo_turtle, publish_demo
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.settle import settle

SECRET = "erasure-scope-secret-" + "s" * 24
EVIL = "https://evil.example/robots/evil/"
TIAGO_NS = "https://example.org/segb/robots/tiago/v1/"
CARLOS, TIAGO = TIAGO_NS + "human_carlos", TIAGO_NS + "robot_tiago"
MARIA = "https://example.org/segb/robots/ari/v1/human_maria"
HUMAN_CLASS = "http://kb.openrobots.org#Human"
ONYX, OA = "http://www.gsi.upm.es/ontologies/onyx/ns#", "http://www.w3.org/ns/oa#"
PLANTED = f"""
<{EVIL}ann1> <{OA}hasTarget> <{EVIL}human_attr> ; <{ONYX}hasEmotion> <{CARLOS}> .
<{EVIL}ann2> <{OA}hasTarget> <{EVIL}human_attr> ; <{ONYX}hasEmotion> <{TIAGO}> .
"""
# The same robot then makes its target look like a person and its resources like annotations (all its own
# subjects, which its token may write).
TYPED = f"""
<{EVIL}human_attr> a <{HUMAN_CLASS}> .
<{EVIL}ann1> a <{OA}Annotation> . <{EVIL}ann2> a <{OA}Annotation> .
"""


def token(roles: list[str], scopes: tuple[str, ...] = ()) -> str:
    return mint_token(SECRET, username="-".join(roles), roles=roles, scopes=scopes).token


ADMIN = token(["admin"])
AS_ADMIN = {"Authorization": f"Bearer {ADMIN}"}


def events(url: str) -> set[str]:
    text = httpx.get(f"{url}/events", params={"format": "ntriples"}, headers=AS_ADMIN, timeout=60).text
    return {line for line in text.splitlines() if line.strip()}


def naming(lines: set[str], *iris: str) -> set[str]:
    """The lines naming one of `iris`, apart from the planting robot's own."""
    return {line for line in lines if any(f"<{iri}>" in line for iri in iris) and not line.startswith(f"<{EVIL}")}


def erase(url: str, body: dict[str, Any]) -> httpx.Response:
    return httpx.post(f"{url}/humans/erase", json=body, headers=AS_ADMIN, timeout=120)


def ledger(url: str) -> list[dict[str, Any]]:
    return httpx.get(f"{url}/ledger", params={"limit": 1000}, headers=AS_ADMIN).json()["receipts"]


def republish(url: str) -> dict[str, Any]:
    """The demo made again by the robot client (its emotions and state properties get new IRIs) and sent whole."""
    resolver = HTTPSharedContextResolver(base_url=url, token=ADMIN, raise_on_error=True)
    try:
        turtle = demo_turtle(lambda robot: resolver)
    finally:
        resolver.close()
    answer: dict[str, Any] = SEGBPublisher(base_url=url, token=ADMIN, default_user="segb-demo").publish_turtle(turtle)
    return answer


@dataclass
class Scenario:
    url: str
    before: set[str] = field(default_factory=set)
    answers: dict[str, httpx.Response] = field(default_factory=dict)
    notes: dict[str, Any] = field(default_factory=dict)


@pytest.fixture(scope="module")
def attacked(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Scenario]:
    """The demo, then a robot scoped to its own namespace planting links to Carlos and TIAGo; an admin erases its
    made-up person, untyped, then typed; then someone erases a class; then the demo is published again."""
    settings = make_settings(store="oxigraph", data_dir=tmp_path_factory.mktemp("attacked"), secret_key=SECRET)
    with LiveServer(create_app(settings)) as server:
        assert "demo dataset published" in publish_demo(server.url, ADMIN)
        settle(server.url)
        scenario = Scenario(server.url, events(server.url))
        evil = {"Authorization": f"Bearer {token(['logger'], (EVIL,))}"}
        for name, turtle in (("planted", PLANTED), ("typed", TYPED)):
            scenario.answers[name] = httpx.post(f"{server.url}/ttl", json={"ttl_content": turtle}, headers=evil)
            if name == "planted":
                settle(server.url)
                scenario.answers["untyped"] = erase(server.url, {"iri": EVIL + "human_attr", "reason": "request"})
        settle(server.url)
        scenario.answers["preview"] = erase(server.url, {"iri": EVIL + "human_attr", "dry_run": True})
        scenario.answers["erased"] = erase(server.url, {"iri": EVIL + "human_attr", "reason": "request"})
        settle(server.url)
        scenario.notes["humans"] = httpx.post(
            f"{server.url}/sparql", data={"query": f"SELECT (COUNT(*) AS ?n) {{ ?x a <{HUMAN_CLASS}> }}"},
            headers=AS_ADMIN,
        ).json()["results"]["bindings"][0]["n"]["value"]  # fmt: skip
        scenario.answers["class"] = erase(server.url, {"iri": HUMAN_CLASS, "reason": "request"})
        scenario.answers["class_preview"] = erase(server.url, {"iri": HUMAN_CLASS, "dry_run": True})
        scenario.answers["robot"] = erase(server.url, {"iri": TIAGO, "reason": "request"})
        scenario.notes["ledger"] = ledger(server.url)
        scenario.notes["republished"] = republish(server.url)
        settle(server.url)
        yield scenario


def test_planted_links_to_others_erase_only_the_planting_robots_own_resources(attacked: Scenario) -> None:
    assert [attacked.answers[name].status_code for name in ("planted", "typed")] == [201, 201]
    erased = attacked.answers["erased"]
    assert erased.status_code == 200, erased.text
    assert erased.json()["resources"] == 3  # its made-up person and its two annotations, nothing else
    after = events(attacked.url)
    carlos_and_tiago = naming(attacked.before, CARLOS, TIAGO)
    assert len(carlos_and_tiago) > 20 and carlos_and_tiago <= after
    assert not [line for line in after if line.startswith(f"<{EVIL}")]
    # Published again, the demo has nothing withheld: nothing of Carlos or TIAGo was erased.
    assert attacked.notes["republished"]["triples_withheld"] == 0


def test_an_iri_the_log_does_not_type_as_a_person_is_refused(attacked: Scenario) -> None:
    untyped = attacked.answers["untyped"]
    assert (untyped.status_code, untyped.json()["error"]) == (422, "invalid_parameter"), untyped.text
    assert "does not type" in untyped.json()["detail"] and "oro:Human" in untyped.json()["detail"]


def test_a_class_or_a_robot_is_refused_and_nothing_is_erased(attacked: Scenario) -> None:
    for name in ("class", "class_preview", "robot"):
        answer = attacked.answers[name]
        assert (answer.status_code, answer.json()["error"]) == (422, "invalid_parameter"), answer.text
        assert "is not a person" in answer.json()["detail"]
    assert "class or a predicate" in attacked.answers["class"].json()["detail"]
    assert [receipt["action"] for receipt in attacked.notes["ledger"]].count("erase") == 1  # the robot's own alone
    assert int(attacked.notes["humans"]) == len(naming(events(attacked.url), HUMAN_CLASS)) >= 2


def test_a_preview_counts_what_the_erasure_then_takes(attacked: Scenario) -> None:
    preview = attacked.answers["preview"].json()
    assert attacked.answers["preview"].status_code == 200 and preview["dry_run"] is True
    assert (preview["resources"], preview["kinds"]) == (3, {"emotion": 2, "human": 1})
    assert preview["resources"] == attacked.answers["erased"].json()["resources"]
    assert preview["triples"] == attacked.answers["erased"].json()["triples_removed"] == 7


@pytest.fixture(scope="module")
def maria_erased(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Scenario]:
    """The demo; requests naming Maria's IRI in their path; a dry run of her erasure; her erasure; the demo sent
    again (new emotions in her erased annotations)."""
    settings = make_settings(store="oxigraph", data_dir=tmp_path_factory.mktemp("maria"), secret_key=SECRET)
    with LiveServer(create_app(settings)) as server:
        assert "demo dataset published" in publish_demo(server.url, ADMIN)
        settle(server.url)
        scenario = Scenario(server.url, events(server.url))
        for path in (f"/humans/{MARIA}", f"/humans/{MARIA}/"):  # mistyped: no /export
            assert httpx.get(f"{server.url}{path}", headers=AS_ADMIN).status_code in (404, 405)
        scenario.notes["log_before"] = httpx.get(
            f"{server.url}/logs/server", params={"limit": 2000}, headers=AS_ADMIN
        ).text
        scenario.notes["ledger_before"] = ledger(server.url)
        scenario.answers["preview"] = erase(server.url, {"iri": MARIA, "dry_run": True})
        scenario.notes["after_preview"] = (events(server.url), ledger(server.url))
        scenario.answers["erased"] = erase(server.url, {"iri": MARIA, "reason": "Request by the data subject"})
        settle(server.url)
        scenario.notes["erased_events"] = events(server.url)
        scenario.notes["republished"] = republish(server.url)
        settle(server.url)
        scenario.notes["log_after"] = httpx.get(
            f"{server.url}/logs/server", params={"limit": 2000}, headers=AS_ADMIN
        ).text
        yield scenario


def test_a_dry_run_lists_counts_by_kind_and_writes_nothing(maria_erased: Scenario) -> None:
    preview = maria_erased.answers["preview"]
    assert preview.status_code == 200, preview.text
    body = preview.json()
    assert body["kinds"]["message"] >= 5 and body["kinds"]["emotion"] >= 8 and body["kinds"]["shared-event"] >= 4
    assert body["kinds"]["human"] == 1 and sum(body["kinds"].values()) == body["resources"]
    assert body["left_out"] == 0
    still, receipts = maria_erased.notes["after_preview"]
    assert still == maria_erased.before and receipts == maria_erased.notes["ledger_before"]
    erased = maria_erased.answers["erased"].json()
    assert erased["resources"] == body["resources"] and erased["triples_removed"] == body["triples"]


def test_a_republish_after_the_erasure_re_attaches_nothing_to_the_erased_iris(maria_erased: Scenario) -> None:
    assert maria_erased.answers["erased"].status_code == 200
    gone = naming(maria_erased.before, MARIA)
    annotations = {line.split(" ")[0][1:-1] for line in gone if f"<{OA}hasTarget>" in line}
    assert len(annotations) == 4 and not naming(maria_erased.notes["erased_events"], MARIA, *annotations)
    republished = maria_erased.notes["republished"]
    assert republished["triples_withheld"] > 0
    assert not naming(events(maria_erased.url), MARIA, *annotations)  # not her, nor a new emotion in her annotations
    assert naming(events(maria_erased.url), CARLOS) == naming(maria_erased.before, CARLOS)


def test_the_server_log_forgets_the_path_a_request_naming_her_was_logged_as(maria_erased: Scenario) -> None:
    written = logged_path(f"/humans/{MARIA}")
    assert written == "/humans/{iri}/human_maria" and written in maria_erased.notes["log_before"]
    assert "human_maria" not in maria_erased.notes["log_after"]
    assert "/humans/erase" in maria_erased.notes["log_after"]  # the log kept the erasure's own request
