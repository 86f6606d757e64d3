"""GET /graph, /resource and /explain on the lobby scenario, on the embedded store and on Virtuoso."""

from __future__ import annotations

import threading
from pathlib import Path

import httpx
import pytest
from rdflib import Graph, URIRef
from semantic_log_generator import ActivityKind

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.explain.service import FOLLOWED_INCOMING, TOLD_LITERALS, ExplainService
from segb_server.backend.services.graph.service import MAX_NODES, GraphRequest, GraphService
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.views.graph_index import GraphIndex
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.api.test_ingest_client import FIXTURE_FILES
from tests.conftest import FIXTURES, make_settings
from tests.support.in_process import InProcess, publisher_for
from tests.support.scenarios import at, keep_busy, lobby, robot_logger
from tests.support.settle import settle


def get(server: InProcess, path: str, **params: object) -> httpx.Response:
    return server.get(path, params=params)  # type: ignore[arg-type]


def test_neighbourhood_of_a_human_holds_their_robot_and_messages(api: InProcess) -> None:
    scenario = lobby()
    scenario.publish_all(api.client)
    iris = {name: str(iri) for name, iri in scenario.iris.items()}
    graph = get(api, "/graph", focus=iris["juan"], depth=3).json()
    nodes = {node["id"]: node for node in graph["nodes"]}
    assert nodes[iris["juan"]]["kind"] == "human" and nodes[iris["juan"]]["label"] == "Juan"
    assert nodes[iris["juan_1"]]["kind"] == "message" and nodes[iris["juan_1"]]["label"] == "Where is the pharmacy?"
    assert nodes[iris["tiago"]]["kind"] == "robot"  # three steps away: message, activity, robot
    assert iris["maria"] not in nodes and iris["ari_1"] not in nodes  # nothing of the other conversation
    assert graph["nodes"][0]["id"] == iris["juan"]  # the focus comes first
    for edge in graph["edges"]:
        assert edge["source"] in nodes and edge["target"] in nodes
    sender = [e for e in graph["edges"] if e["source"] == iris["juan_1"] and e["target"] == iris["juan"]]
    assert [e["label"] for e in sender] == ["sender"]  # the PROV copy of the link is not drawn twice


def test_graph_filters_kinds_time_search_and_limit(api: InProcess) -> None:
    scenario = lobby()
    scenario.publish_all(api.client)
    people = get(api, "/graph", types="robot,human").json()
    assert sorted(node["label"] for node in people["nodes"]) == ["ARI", "Juan", "Maria", "TIAGo"]
    robots = get(api, "/graph", types="oro:Robot").json()  # a class, as the robots typed them
    assert sorted(node["label"] for node in robots["nodes"]) == ["ARI", "TIAGo"] and robots["total_nodes"] == 2
    assert all("oro:Robot" in node["types"] for node in robots["nodes"])
    humans = get(api, "/graph", types="http://kb.openrobots.org#Human,robot").json()  # a class IRI and a kind
    assert sorted(node["label"] for node in humans["nodes"]) == ["ARI", "Juan", "Maria", "TIAGo"]
    window = get(api, "/graph", since="2026-03-10T09:00:08Z", until="2026-03-10T09:00:10Z", types="message").json()
    assert sorted(node["label"] for node in window["nodes"]) == ["Congratulations, Maria!", "Second floor, Juan."]
    found = get(api, "/graph", q="pharmacy").json()
    hits = {(n["kind"], n["label"]) for n in found["nodes"] if n["id"] in found["matches"]}
    assert hits == {("message", "Where is the pharmacy?"), ("shared-event", "Where is the pharmacy?")}
    small = get(api, "/graph", limit=5).json()
    assert len(small["nodes"]) == 5 and small["truncated"] is True
    assert [node["kind"] for node in small["nodes"]][:2] == ["robot", "robot"]  # robots and humans first
    assert small["total_nodes"] > 5


def test_resource_lists_triples_both_ways_with_labels(api: InProcess) -> None:
    scenario = lobby()
    scenario.publish_all(api.client)
    body = get(api, "/resource", iri=str(scenario.iris["maria_1"])).json()
    assert body["kind"] == "message" and body["label"] == "I passed my driving test today!"
    out = {(s["predicate_label"], s.get("label") or s["value"]) for s in body["outgoing"]}
    assert ("schema:sender", "Maria") in out and ("schema:text", "I passed my driving test today!") in out
    text = next(s for s in body["outgoing"] if s["predicate_label"] == "schema:text")
    assert text["is_literal"] and text["language"] == "en"
    incoming = {(s["predicate_label"], s["value"]) for s in body["incoming"]}
    assert ("prov:wasDerivedFrom", str(scenario.iris["ari_1"])) in incoming


def test_a_resource_many_things_point_at_is_read_a_page_at_a_time(api: InProcess) -> None:
    """A robot after a month is the object of one link per activity: the details read the first 500 and say
    more exist; an explanation around one of its activities still names the robot and tells only that act."""
    scenario = lobby()
    scenario.publish_all(api.client)
    tiago = str(scenario.iris["tiago"])
    keep_busy(api.client, tiago, 600)
    body = get(api, "/resource", iri=tiago).json()
    assert len(body["incoming"]) == 500 and body["incoming_truncated"] is True
    assert body["incoming"] == sorted(body["incoming"], key=lambda s: (s["predicate"], str(s["value"])))
    small = get(api, "/resource", iri=str(scenario.iris["maria_1"])).json()
    assert small["incoming_truncated"] is False

    story = get(api, "/explain", iri=str(scenario.iris["juan_1"])).json()
    assert {step["robot"]["label"] for step in story["steps"]} == {"TIAGo"}
    assert not any("busy" in step["activity"] for step in story["steps"])


def test_explain_a_reply_gives_what_was_heard_the_models_and_the_trigger_in_order(api: InProcess) -> None:
    scenario = lobby()
    scenario.publish_all(api.client)
    iris = {name: str(iri) for name, iri in scenario.iris.items()}
    story = get(api, "/explain", iri=iris["ari_1"]).json()
    steps = story["steps"]
    assert [step["activity"] for step in steps] == [
        iris["listen_maria_1"], iris["emotion_maria_1"], iris["reply_maria_1"], iris["listen_maria_2"]
    ]  # fmt: skip
    assert [step["role"] for step in steps] == ["cause", "cause", "seed", "effect"]
    heard, analysed, reply = steps[0], steps[1], steps[2]
    assert heard["heard"][0]["text"] == "I passed my driving test today!"
    assert heard["heard"][0]["sender"]["label"] == "Maria"
    assert heard["events"][0]["modalities"] == ["speech"]
    assert [(m["label"], m["version"]) for m in analysed["models"]] == [("Emotion Big6 CNN", "1.0")]
    assert analysed["emotions"][0]["category"] == "happiness"
    assert analysed["emotions"][0]["intensity"] == pytest.approx(0.9)
    assert set(reply["triggered_by"]) == {iris["emotion_maria_1"], iris["listen_maria_1"]}
    assert reply["said"][0]["text"] == "Congratulations, Maria!" and reply["robot"]["label"] == "ARI"


def test_words_heard_from_nobody_named_are_not_the_robots_until_the_log_names_a_speaker(api: InProcess) -> None:
    """Who said a message, in the conversations report and in its explanation, follows what the log names: an
    utterance TIAGo only heard is an unidentified speaker's; a later post naming Maria as its sender makes it
    hers; a reply its response activity produced is TIAGo's."""
    tiago = robot_logger("tiago", "TIAGo")
    maria = tiago.register_human("maria", first_name="Maria")
    heard = tiago.log_activity(activity_id="overhear", activity_kind=ActivityKind.LISTENING, started_at=at(1))
    words = tiago.log_message("Is it raining?", message_id="overheard", language="en", generated_by_activity=heard)
    answer = tiago.log_activity(activity_id="reply", activity_kind=ActivityKind.RESPONSE, started_at=at(2))
    tiago.log_message("Not yet.", message_id="reply", generated_by_activity=answer)
    publisher = publisher_for(api.client)

    def told() -> tuple[list[tuple[object, object]], str]:
        settle(api.client)
        rows = api.get("/reports/conversations").json()["rows"]
        story = api.get("/explain", params={"iri": str(words)}).json()
        seed = next(step for step in story["steps"] if step["role"] == "seed")
        return sorted((row["text"], row["speaker"]) for row in rows), seed["sentence"]

    tiago.publish(publisher)
    rows, sentence = told()
    assert rows == [("Is it raining?", "unidentified"), ("Not yet.", "robot")]
    assert sentence == "An unidentified speaker said “Is it raining?” (heard by TIAGo)"

    tiago.log_message("Is it raining?", message_id="overheard", language="en", sender=maria)  # named later
    tiago.publish(publisher)
    rows, sentence = told()
    assert rows == [("Is it raining?", "human"), ("Not yet.", "robot")]
    assert sentence == "Maria said “Is it raining?” (heard by TIAGo)"


@pytest.mark.parametrize(
    ("path", "params", "status", "named"),
    [
        ("/graph", {"focus": "not an iri"}, 422, "focus"),
        ("/graph", {"since": "yesterday"}, 422, "since"),
        ("/graph", {"types": "robots"}, 422, "types"),
        ("/graph", {"limit": "0"}, 422, "limit"),
        ("/resource", {}, 422, "iri"),
        ("/explain", {"iri": "https://example.org/nothing-here"}, 404, "Nothing is known"),
    ],
)
def test_bad_graph_requests_name_the_problem(
    memory_api: InProcess, path: str, params: dict, status: int, named: str
) -> None:
    response = get(memory_api, path, **params)
    assert response.status_code == status
    assert named in response.text


def test_resources_read_together_equal_each_read_alone(api: InProcess, store: Store) -> None:
    """An explanation reads its nodes in batches: two queries for many resources must describe each one as
    reading it alone does, also when the batch reaches its limit and falls back to one resource at a time."""
    scenario = lobby()
    scenario.publish_all(api.client)
    graph = GraphService(Catalog(PACKAGE_ROOT / "sparql"), store, None, lambda _: True)  # type: ignore[arg-type]
    iris = sorted({str(iri) for iri in scenario.iris.values()})
    together = graph.resources(iris, incoming=FOLLOWED_INCOMING)
    assert together == {iri: graph.resource(iri, incoming=FOLLOWED_INCOMING) for iri in iris}
    # One incoming statement each: the batch reaches its limit. Which statement a store returns first is its
    # own choice, so the rest of each description is compared, and how many came and whether more were left.
    together = graph.resources(iris, incoming=FOLLOWED_INCOMING, incoming_limit=1)
    alone = {iri: graph.resource(iri, incoming=FOLLOWED_INCOMING, incoming_limit=1) for iri in iris}
    assert any(node["incoming_truncated"] for node in alone.values())
    for iri in iris:
        one, other = dict(together[iri]), dict(alone[iri])
        assert len(one.pop("incoming")) == len(other.pop("incoming")) <= 1  # type: ignore[arg-type]
        assert one == other, iri
    described = graph.resources(iris)
    assert sum(len(node["incoming"]) for node in described.values()) > 0  # type: ignore[arg-type]
    assert described[str(scenario.iris["juan_1"])]["label"] == "Where is the pharmacy?"


EXPLAINED_KINDS = ("activity", "message", "emotion", "state", "shared-event")  # what /explain tells the story of


def test_explanations_from_the_graph_index_equal_those_from_the_store(
    api: InProcess, store: Store, tmp_path: Path
) -> None:
    """Once built, the graph index stands in for the store when an explanation reads its nodes: every story it
    tells must be the one the store's own statements tell, for every message, activity, emotion and state of
    the scenario and of the client's fixtures (versions, confidences and intensities included)."""
    lobby().publish_all(api.client)
    for name in FIXTURE_FILES:
        text = (FIXTURES / name).read_text(encoding="utf-8")
        assert api.post("/ttl", json={"ttl_content": text, "user": "fixtures"}).status_code == 201
    catalog = Catalog(PACKAGE_ROOT / "sparql")
    index = GraphIndex(store, tmp_path / "graph.sqlite3", detail_literals=TOLD_LITERALS)
    index.build(through=0)
    index.ready = True
    from_index = ExplainService(GraphService(catalog, store, index, lambda _: True))
    unbuilt = GraphIndex(store, tmp_path / "unbuilt.sqlite3")
    from_store = ExplainService(GraphService(catalog, store, unbuilt, lambda _: False))
    drawn = index.view(GraphRequest(limit=MAX_NODES))["nodes"]
    seeds = [str(node["id"]) for node in drawn if node["kind"] in EXPLAINED_KINDS]  # type: ignore[index]
    stories = []
    for iri in seeds:
        expected = from_store.explain(iri)
        assert from_index.explain(iri) == expected, iri
        stories.append(expected)
    assert sum(bool(story["steps"]) for story in stories) > 50
    assert any(story["seed"]["kind"] == "shared-event" and story["steps"] for story in stories)
    assert any(model["version"] for story in stories for step in story["steps"] for model in step["models"])
    assert any(emotion["confidence"] for story in stories for step in story["steps"] for emotion in step["emotions"])
    index.close()
    unbuilt.close()


@pytest.mark.slow
def test_explanations_from_an_index_behind_the_store_and_the_steps_on_their_way_equal_those_from_the_store(
    api: InProcess, store: Store, tmp_path: Path
) -> None:
    """An explanation asked right after a 201 reads the index and adds the steps it does not hold yet: told
    with the posts the index has not seen (here every fixture, given along with triples it already holds), each
    story must be the store's."""
    lobby().publish_all(api.client)
    catalog = Catalog(PACKAGE_ROOT / "sparql")
    index = GraphIndex(store, tmp_path / "graph.sqlite3", detail_literals=TOLD_LITERALS)
    index.build(through=0)  # the lobby only
    index.ready = True
    for name in FIXTURE_FILES:
        text = (FIXTURES / name).read_text(encoding="utf-8")
        assert api.post("/ttl", json={"ttl_content": text, "user": "fixtures"}).status_code == 201
    everything = [quad for batch in store.batches(20_000) for quad in batch]
    behind = ExplainService(GraphService(catalog, store, index, lambda _: True))
    caught_up = ExplainService(GraphService(catalog, store, index, lambda _: True, pending=lambda _limit: everything))
    unbuilt = GraphIndex(store, tmp_path / "unbuilt.sqlite3")
    from_store = ExplainService(GraphService(catalog, store, unbuilt, lambda _: False))
    complete = GraphIndex(store, tmp_path / "complete.sqlite3")
    complete.build(through=0)
    drawn = complete.view(GraphRequest(limit=MAX_NODES))["nodes"]
    seeds = [str(node["id"]) for node in drawn if node["kind"] in EXPLAINED_KINDS]  # type: ignore[index]
    told_late = 0
    for iri in seeds:
        expected = from_store.explain(iri)
        assert caught_up.explain(iri) == expected, iri
        try:
            told_late += behind.explain(iri) != expected
        except NotFound:  # unknown to the index alone
            told_late += 1
    assert told_late > 20  # the index alone missed the fixtures' stories: the steps on their way told them
    for opened in (index, unbuilt, complete):
        opened.close()


def test_an_explanation_asked_right_after_a_201_tells_that_post_and_after_a_clearing_nothing(tmp_path: Path) -> None:
    """The views follow the store a little behind it (their upkeep runs after the 201): an explanation must not.
    While another robot keeps the views busy, after each robot's publish every scenario IRI in what it sent is
    explained; after the clearing's 201, none. What answers is the index and the journal, whatever the store: the
    embedded one keeps the views busiest for the same posts (its upkeep is this process's own work)."""
    store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    with InProcess(create_app(make_settings(), store=store)) as api:
        _explain_under_a_stream_of_posts(api)
    store.close()


def _explain_under_a_stream_of_posts(api: InProcess) -> None:
    stop = threading.Event()
    busy = threading.Thread(target=_post_until, args=(api.client, stop), daemon=True)
    busy.start()
    try:
        _explain_each_publish_then_clear(api)
    finally:
        stop.set()
        busy.join()


def _post_until(client: httpx.Client, stop: threading.Event) -> None:
    """Small posts one after another (a robot logging fast), until `stop`."""
    n = 0
    while not stop.is_set():
        n += 1
        ttl = (
            f"<https://example.org/fast/a{n}> a <http://www.w3.org/ns/prov#Activity> ; "
            f'<http://www.w3.org/2000/01/rdf-schema#label> "step {n}" .'
        )
        assert client.post("/ttl", json={"ttl_content": ttl, "user": "fast"}).status_code == 201


def _explain_each_publish_then_clear(api: InProcess) -> None:
    scenario = lobby()
    publishers = {name: publisher_for(api.client, name) for name in scenario.loggers}
    explained: set[str] = set()

    def publish_and_explain(robot: str) -> None:
        scenario.loggers[robot].publish(publishers[robot])
        sent = Graph().parse(data=scenario.loggers[robot].serialize(), format="turtle")
        for iri in {str(iri) for iri in scenario.iris.values()}:
            if (URIRef(iri), None, None) in sent:
                response = get(api, "/explain", iri=iri)
                assert response.status_code == 200, (iri, response.text)
                explained.add(iri)

    scenario.run_steps(publish_and_explain)
    assert len(explained) > 10
    response = api.post("/ttl/delete_all", json={"user": "auditor"})
    assert response.status_code in (200, 201), response.text
    for iri in sorted(explained):
        assert get(api, "/explain", iri=iri).status_code == 404, iri
