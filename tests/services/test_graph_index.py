"""The graph index on its own (the embedded store and the index in memory), on the client's shapes: what a node
is and is called, the time a message borrows from its activity even when the activity's time comes later, the
links drawn once, a clearing, and the statements it can tell in the store's place."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator

import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.graph.candidates import CandidateQuery
from segb_server.backend.services.views import graph_index
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.graph_index import GraphIndex, GraphRequest
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.vocabulary import PREFIXES

EX = "https://example.org/robots/ari/"
RDF_TYPE = PREFIXES["rdf"] + "type"
XSD = "http://www.w3.org/2001/XMLSchema#"
ROBOT, HUMAN, ACTIVITY, MESSAGE = EX + "robot_ari", EX + "human_maria", EX + "activity_listen_1", EX + "message_1"


def triple(subject: str, predicate: str, value: str | Literal) -> Quad:
    prefix, _, local = predicate.partition(":")
    target = value if isinstance(value, Literal) else NamedNode(value)
    return Quad(NamedNode(subject), NamedNode(PREFIXES[prefix] + local), target)


def a(subject: str, kind: str) -> Quad:
    prefix, _, local = kind.partition(":")
    return Quad(NamedNode(subject), NamedNode(RDF_TYPE), NamedNode(PREFIXES[prefix] + local))


PEOPLE = [
    a(ROBOT, "oro:Robot"),
    triple(ROBOT, "schema:name", Literal("ARI", language="en")),
    a(HUMAN, "oro:Human"),
    triple(HUMAN, "foaf:firstName", Literal("Maria", language="en")),
]
SAID = [
    a(MESSAGE, "schema:Message"),
    triple(MESSAGE, "schema:text", Literal("Hello, ARI", language="en")),
    triple(MESSAGE, "schema:sender", HUMAN),
    triple(MESSAGE, "prov:wasAttributedTo", HUMAN),  # the client's PROV copy of the link
    triple(MESSAGE, "prov:wasGeneratedBy", ACTIVITY),
    a(ACTIVITY, "segb:LoggedActivity"),
    triple(ACTIVITY, "segb:wasPerformedBy", ROBOT),
]
WHEN = [
    triple(ACTIVITY, "prov:startedAtTime", Literal("2026-03-10T09:00:01+00:00", datatype=NamedNode(XSD + "dateTime")))
]


@pytest.fixture
def store() -> Iterator[OxigraphStore]:
    opened = OxigraphStore("urn:x:events")
    yield opened
    opened.close()


def kept(store: OxigraphStore, built: list[Quad], *later: list[Quad]) -> GraphIndex:
    """An index built from `built`, then kept current with each of `later` as one applied step."""
    store.apply(built, 1)
    index = GraphIndex(store, None)
    index.build(through=1)
    for through, quads in enumerate(later, start=2):
        store.apply(quads, through)
        index.update(Delta.of(quads), through)
    return index


def nodes(index: GraphIndex, **request: object) -> dict[str, dict[str, object]]:
    return {str(node["id"]): node for node in index.view(GraphRequest(**request))["nodes"]}  # type: ignore[arg-type, index]


def test_nodes_have_their_kind_and_name_and_a_message_its_activitys_time(store: OxigraphStore) -> None:
    index = kept(store, PEOPLE + SAID + WHEN)
    drawn = nodes(index)
    assert {iri: (node["kind"], node["label"]) for iri, node in drawn.items()} == {
        ROBOT: ("robot", "ARI"),
        HUMAN: ("human", "Maria"),
        ACTIVITY: ("activity", "activity_listen_1"),
        MESSAGE: ("message", "Hello, ARI"),
    }
    assert drawn[MESSAGE]["time"] == drawn[ACTIVITY]["time"]
    edges = {(e["source"], e["label"], e["target"]) for e in index.view(GraphRequest())["edges"]}  # type: ignore[index]
    assert (MESSAGE, "sender", HUMAN) in edges and (MESSAGE, "wasAttributedTo", HUMAN) not in edges  # drawn once
    assert (ACTIVITY, "wasPerformedBy", ROBOT) in edges
    index.close()


def test_a_time_that_comes_later_reaches_the_message_that_borrows_it(store: OxigraphStore) -> None:
    index = kept(store, PEOPLE + SAID, WHEN)
    assert "time" in nodes(index)[MESSAGE]
    assert nodes(index, since="2026-03-10T09:00:00Z", types=("message",)).keys() == {MESSAGE}
    assert nodes(index, since="2026-03-10T10:00:00Z", types=("message",)) == {}
    assert index.stored_through() == 2
    index.close()


def test_the_index_kept_current_draws_what_a_fresh_one_draws(store: OxigraphStore) -> None:
    index = kept(store, PEOPLE, SAID, WHEN)
    fresh = GraphIndex(store, None)
    fresh.build(through=3)
    for request in (GraphRequest(), GraphRequest(focus=HUMAN, depth=2), GraphRequest(robot=ROBOT)):
        assert index.view(request) == fresh.view(request), request
    index.close()
    fresh.close()


def test_a_clearing_empties_it_and_what_follows_is_drawn_again(store: OxigraphStore) -> None:
    index = kept(store, PEOPLE + SAID + WHEN)
    store.clear(through=2)
    index.clear(through=2)
    assert nodes(index) == {} and index.stored_through() == 2
    store.apply(PEOPLE, 3)
    index.update(Delta.of(PEOPLE), 3)
    assert nodes(index).keys() == {ROBOT, HUMAN}
    index.close()


def test_its_statements_stand_in_for_the_stores_about_a_node(store: OxigraphStore) -> None:
    index = kept(store, PEOPLE + SAID + WHEN)
    outgoing, incoming = index.statements([MESSAGE], incoming={PREFIXES["prov"] + "wasGeneratedBy"}, incoming_limit=5)
    told = {(str(row["predicate"].value), str(row["value"].value)) for row in outgoing}  # type: ignore[union-attr]
    assert (PREFIXES["schema"] + "sender", HUMAN) in told
    assert (PREFIXES["schema"] + "text", "Hello, ARI") in told  # a literal that names the node, kept whole
    assert incoming == []  # nothing is generated by the message
    index.close()


def test_a_class_filter_finds_a_nodes_classes_whichever_step_brought_them(store: OxigraphStore) -> None:
    # Maria is a person first, a human a step later; an unprefixed class comes last.
    unlisted = "https://example.org/classes/Visitor"
    typed = [Quad(NamedNode(HUMAN), NamedNode(RDF_TYPE), NamedNode(unlisted))]
    index = kept(store, [*PEOPLE[:1], a(HUMAN, "foaf:Person"), PEOPLE[3]], PEOPLE[1:3] + SAID, typed)
    assert nodes(index)[HUMAN]["types"] == sorted(["foaf:Person", "oro:Human", unlisted])
    assert nodes(index)[HUMAN]["kind"] == "human"  # the kind follows the type that came later
    assert nodes(index, types=("oro:Human",)).keys() == {HUMAN}
    assert nodes(index, types=(PREFIXES["foaf"] + "Person",)).keys() == {HUMAN}  # as an IRI
    assert nodes(index, types=(unlisted, "robot")).keys() == {HUMAN, ROBOT}
    assert nodes(index, types=("schema:Person",)) == {}
    outgoing, _ = index.statements([HUMAN], incoming=set(), incoming_limit=5)
    told = {str(row["value"].value) for row in outgoing if row["predicate"] == NamedNode(RDF_TYPE)}  # type: ignore[union-attr]
    assert told == {PREFIXES["foaf"] + "Person", PREFIXES["oro"] + "Human", unlisted}
    lists = [row[0] for row in index.db.reader().execute("SELECT types FROM graph_typesets WHERE types != '[]'")]
    assert len(lists) == 4  # the robot's, the message's, the activity's and Maria's: none she held before
    fresh = GraphIndex(store, None)
    fresh.build(through=4)
    for request in (GraphRequest(), GraphRequest(types=("oro:Human", "message"))):
        assert index.view(request) == fresh.view(request), request
    index.close()
    fresh.close()


def test_a_time_window_reads_ranges_of_the_drawing_orders_index(store: OxigraphStore) -> None:
    # The nodes keep no index of their instants: a window is a range of them within each kind's part of the
    # drawing order's index, not a scan of every node.
    index = kept(store, PEOPLE + SAID + WHEN)
    request = GraphRequest(since="2026-03-10T09:00:00Z", until="2026-03-10T10:00:00Z")
    text, arguments = CandidateQuery(request, {}).ordered(request.limit)
    plan = [row[3] for row in index.db.reader().execute(f"EXPLAIN QUERY PLAN {text}", arguments)]
    assert "SEARCH graph_nodes USING COVERING INDEX graph_nodes_order (rank=? AND instant>? AND instant<?)" in plan
    assert not any(step.startswith("SCAN graph_nodes") for step in plan), plan
    assert nodes(index, since=request.since, until=request.until).keys() == {ACTIVITY, MESSAGE, ROBOT, HUMAN}
    index.close()


def test_a_node_typed_again_and_again_keeps_one_list_of_its_types(store: OxigraphStore) -> None:
    # A robot adding a class to one node in every post: the lists it leaves behind go, or they would hold the
    # square of its classes.
    steps = [[Quad(NamedNode(HUMAN), NamedNode(RDF_TYPE), NamedNode(f"https://example.org/classes/C{n}"))]
             for n in range(60)]  # fmt: skip
    index = kept(store, PEOPLE, *steps)
    lists = [row[0] for row in index.db.reader().execute("SELECT types FROM graph_typesets WHERE types != '[]'")]
    assert len(lists) == 2 and sum(len(listed) for listed in lists) < 60 * 40 + 200  # the robot's and hers
    assert len(nodes(index)[HUMAN]["types"]) == 61
    assert nodes(index, types=("https://example.org/classes/C7",)).keys() == {HUMAN}
    index.close()


def test_a_step_whose_write_failed_leaves_no_ids_behind_in_the_writers_memory(
    store: OxigraphStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A write that fails (a full disk) rolls its transaction back, ids made in it included: taking the step again
    must make them again, not reuse ids the tables never kept."""
    index = kept(store, PEOPLE)
    store.apply(SAID + WHEN, 2)

    def disk_full(*_: object) -> None:
        raise sqlite3.OperationalError("database or disk is full")

    with monkeypatch.context() as patched:
        patched.setattr(graph_index, "_record_changes", disk_full)
        with pytest.raises(sqlite3.OperationalError):
            index.update(Delta.of(SAID + WHEN), 2)
    index.update(Delta.of(SAID + WHEN), 2)  # the step taken again
    fresh = GraphIndex(store, None)
    fresh.build(through=2)
    for request in (GraphRequest(), GraphRequest(types=("oro:Human",)), GraphRequest(focus=MESSAGE)):
        assert index.view(request) == fresh.view(request), request
    assert set(nodes(index)) == {ROBOT, HUMAN, ACTIVITY, MESSAGE}
    fresh.close()
    index.close()
