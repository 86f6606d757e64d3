"""The graph index kept current from the journal's stream draws the same graph as an index built afresh from
the store: after every step of random histories (late links, out-of-order times, re-publishes, clearings), on
both stores, for the first view, a robot's part and a neighbourhood; and after a restart that finds the index
behind the journal (caught up, not built again)."""

from __future__ import annotations

import logging
import shutil
import sqlite3
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT, Settings
from segb_server.backend.services.container import GRAPH_FILE
from segb_server.backend.services.graph.service import GraphService
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.views import graph_index
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.graph_index import (
    FIRST_VIEW,
    INDEX_VERSION,
    RDF_TYPE,
    GraphIndex,
    GraphRequest,
)
from segb_server.backend.services.views.keeper import ViewKeeper
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.state.sqlite import SqliteDatabase
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import STORE_KINDS, make_settings, virtuoso_store
from tests.support.histories import EX, History
from tests.support.in_process import InProcess, Server, http
from tests.support.settle import settle

XSD_DATETIME = "http://www.w3.org/2001/XMLSchema#dateTime"

REQUESTS = [
    GraphRequest(limit=20_000),
    GraphRequest(limit=20_000, robot=f"{EX}robot/ari"),
    GraphRequest(limit=20_000, focus=f"{EX}human/maria", depth=2),
    GraphRequest(focus=f"{EX}robot/ari", depth=1),  # kept between the changes that reach it
    GraphRequest(limit=30),  # the first view cut short: which nodes come first matters too
    GraphRequest(),  # the kg-graph's first view, which is kept between changes that reach it
]


def served(server: Server, request: GraphRequest) -> dict[str, object]:
    params: dict[str, object] = {"limit": request.limit}
    if request.robot:
        params["robot"] = request.robot
    if request.focus:
        params.update(focus=request.focus, depth=request.depth)
    answer = http(server, "GET", "/graph", params=params)
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert isinstance(body.pop("through"), int)  # the journal entry the drawing includes, for live viewers
    return body


def fresh(store: Store, request: GraphRequest) -> dict[str, object]:
    index = GraphIndex(store, None)
    try:
        index.build(0)
        return index.view(request)
    finally:
        index.close()


def count_draws(index: GraphIndex) -> list[GraphRequest]:
    """The requests `index` draws from its tables from now on (a kept view is not drawn)."""
    drawn: list[GraphRequest] = []
    draw = index._drawn_and_reached

    def counted(connection: object, request: GraphRequest) -> tuple[dict[str, object], frozenset[str] | None]:
        drawn.append(request)
        return draw(connection, request)

    index._drawn_and_reached = counted  # type: ignore[method-assign]
    return drawn


def count_view_draws(index: GraphIndex) -> list[GraphRequest]:
    """The views `index` draws from its tables from now on, the first view among them (a kept one is not drawn)."""
    drawn: list[GraphRequest] = []
    draw = index._view

    def counted(connection: Any, request: GraphRequest) -> dict[str, object]:
        drawn.append(request)
        return draw(connection, request)

    index._view = counted  # type: ignore[method-assign]
    return drawn


def post(server: Server, triples: list[str] | None) -> None:
    if triples is None:
        assert http(server, "POST", "/ttl/delete_all", json={}).status_code == 200
        return
    answer = http(server, "POST", "/ttl", content="\n".join(triples), headers={"Content-Type": "application/n-triples"})
    assert answer.status_code == 201, answer.text


@pytest.fixture(params=STORE_KINDS)
def server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[Server, Store]]:
    if request.param == "virtuoso":
        store: Store = virtuoso_store(request.getfixturevalue("virtuoso"))
    else:
        store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    with InProcess(create_app(make_settings(store=request.param, data_dir=tmp_path), store=store)) as live:
        yield live.client, store
    if request.param == "virtuoso":
        store.clear()
    store.close()


def test_the_graph_kept_current_equals_a_fresh_index_after_every_step(server: tuple[Server, Store]) -> None:
    url, store = server
    history = History(7)
    for step in range(14):
        post(url, history.next_post())
        settle(url)
        for request in REQUESTS:
            assert served(url, request) == fresh(store, request), (step, request)
        # The first view's total is a kept count: it must still be every node there is to draw.
        everything, first = served(url, REQUESTS[0]), served(url, REQUESTS[-1])
        assert first["total_nodes"] == len(everything["nodes"]) == everything["total_nodes"], step  # type: ignore[arg-type]
    assert served(url, REQUESTS[0])["nodes"], "the history left something to draw"


def served_history(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, *, seed: int, posts: int
) -> tuple[OxigraphStore, Settings, History]:
    """An on-disk store and data directory after a server received `posts` steps of a history and stopped (the
    views' log lines captured)."""
    store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    settings = make_settings(store="oxigraph", data_dir=tmp_path / "data")
    history = History(seed)
    caplog.set_level(logging.INFO, logger="segb.views")
    with InProcess(create_app(settings, store=store)) as live:
        for _ in range(posts):
            post(live.client, history.next_post() or [])
        settle(live.client)
    return store, settings, history


def test_a_restart_catches_the_index_up_from_the_journal(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    store, settings, history = served_history(tmp_path, caplog, seed=3, posts=4)
    try:
        assert any(record.getMessage().startswith("view graph built") for record in caplog.records)
        behind = tmp_path / "graph-behind.sqlite3"
        shutil.copy(settings.data_dir / GRAPH_FILE, behind)
        with InProcess(create_app(settings, store=store)) as live:
            for _ in range(6):
                triples = history.next_post()
                if triples is not None:  # a clearing would make the restart build the index again
                    post(live.client, triples)
            settle(live.client)
            current = served(live.client, REQUESTS[0])
        shutil.copy(behind, settings.data_dir / GRAPH_FILE)  # as if the last posts were never projected
        caplog.clear()
        with InProcess(create_app(settings, store=store)) as live:
            settle(live.client)
            assert served(live.client, REQUESTS[0]) == current == fresh(store, REQUESTS[0])
        built = [record.getMessage() for record in caplog.records if record.getMessage().startswith("view graph built")]
        assert built == []  # caught up from the journal, not built again from the store
    finally:
        store.close()


def test_an_index_kept_from_before_a_restart_draws_its_first_view_before_the_first_request(tmp_path: Path) -> None:
    """At a restart the stored index is current (nothing to build or catch up): its first view is drawn as the
    views get ready, as at a build, so the first visitor does not wait for it."""
    store = OxigraphStore("http://amor-segb/events")
    activity = NamedNode(f"{EX}activity/1")
    store.apply([Quad(activity, NamedNode("http://www.w3.org/2000/01/rdf-schema#label"), Literal("greeting"))], 1)
    before = GraphIndex(store, tmp_path / "graph.sqlite3")
    before.build(1)
    before.close()
    restarted = GraphIndex(store, tmp_path / "graph.sqlite3")
    draws = count_view_draws(restarted)
    projector = ViewKeeper(store, Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [restarted])
    projector.start()
    try:
        assert projector.progress.wait_for(1, timeout=10)
        assert draws == [FIRST_VIEW]
        assert restarted.view(FIRST_VIEW) == fresh(store, FIRST_VIEW)
        assert draws == [FIRST_VIEW]  # the first request found it drawn
    finally:
        projector.stop()
        restarted.close()
        store.close()


def test_an_index_written_with_other_tables_is_built_again_at_start(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """An index left by a version whose tables differ (here: its state without the first view's counter, and the
    version number of then) is built again from the store, never updated in place (which failed on the missing
    column, and dropped every view)."""
    store, settings, history = served_history(tmp_path, caplog, seed=5, posts=3)
    try:
        database = sqlite3.connect(settings.data_dir / GRAPH_FILE)
        database.execute("ALTER TABLE graph_state DROP COLUMN first_view")
        database.execute("UPDATE graph_state SET version = ?", (INDEX_VERSION,))
        database.commit()
        database.close()
        caplog.clear()
        with InProcess(create_app(settings, store=store)) as live:
            settle(live.client)
            post(live.client, history.next_post() or [])
            settle(live.client)
            for request in (FIRST_VIEW, REQUESTS[0]):
                assert served(live.client, request) == fresh(store, request), request
        messages = [record.getMessage() for record in caplog.records]
        assert any(message.startswith("view graph built") for message in messages)
        assert not any("failed" in message for message in messages), messages
    finally:
        store.close()


def test_the_first_view_is_kept_while_posts_land_after_it_and_drawn_again_when_one_reaches_it(tmp_path: Path) -> None:
    """Under a stream of posts the first view (1,500 nodes of a bigger graph) is kept: new activities sort
    after its last node. A change that reaches it (a link between two of its nodes, an earlier activity that
    enters it) draws it again; whichever happened, it equals the view of an index built afresh."""
    prov, segb = "http://www.w3.org/ns/prov#", "http://www.gsi.upm.es/ontologies/segb/ns#"
    robot = NamedNode(f"{EX}robot/ari")

    def activity(number: int, time: str) -> list[Quad]:
        node = NamedNode(f"{EX}activity/{number}")
        return [
            Quad(node, NamedNode(prov + "startedAtTime"), Literal(time, datatype=NamedNode(XSD_DATETIME))),
            Quad(node, NamedNode(segb + "wasPerformedBy"), robot),
        ]

    store = OxigraphStore("http://amor-segb/events")
    store.apply(
        [q for n in range(2000) for q in activity(n, f"2026-03-10T{n // 3600:02d}:{n // 60 % 60:02d}:{n % 60:02d}Z")], 0
    )
    index = GraphIndex(store, tmp_path / "graph.sqlite3")
    index.build(0)

    def generation() -> int:
        return int(index.db.reader().execute("SELECT first_view FROM graph_state").fetchone()[0])

    def step(quads: list[Quad], through: int) -> None:
        store.apply(quads, through)
        index.update(Delta.of(quads), through)
        assert index.view(FIRST_VIEW) == fresh(store, FIRST_VIEW), through

    first = index.view(FIRST_VIEW)
    assert first["truncated"] and len(first["nodes"]) == FIRST_VIEW.limit  # type: ignore[arg-type]
    kept = generation()
    step(activity(5000, "2026-03-11T00:00:00Z"), 1)  # later than every drawn node
    assert generation() == kept
    assert index.view(FIRST_VIEW)["total_nodes"] == first["total_nodes"] + 1  # type: ignore[operator]
    link = [Quad(NamedNode(f"{EX}activity/0"), NamedNode(segb + "triggeredByActivity"), NamedNode(f"{EX}activity/1"))]
    step(link, 2)
    assert generation() != kept
    kept = generation()
    step(activity(6000, "2026-03-09T00:00:00Z"), 3)  # earlier than every drawn activity: it enters the view
    assert generation() != kept

    def named(number: int) -> list[Quad]:
        label = NamedNode("http://www.w3.org/2000/01/rdf-schema#label")
        return [Quad(NamedNode(f"{EX}activity/{number}"), label, Literal(f"step {number}"))]

    kept = generation()
    step(named(1999), 4)  # a node after the view's last one: its new label is not drawn
    assert generation() == kept
    step(named(10), 5)  # a drawn node's label
    assert generation() != kept
    index.close()
    store.close()


def test_a_watched_first_view_is_drawn_again_by_the_keeper_and_an_unwatched_one_by_nobody(tmp_path: Path) -> None:
    """The first view is drawn when the index is built; a step that changes it draws it again at once while a
    viewer asked for it lately (their next request finds it drawn); nobody asking, the step draws nothing."""
    prov = "http://www.w3.org/ns/prov#"

    def activity(number: int) -> list[Quad]:
        node = NamedNode(f"{EX}activity/{number}")
        time = Literal(f"2026-03-10T00:00:{number:02d}Z", datatype=NamedNode(XSD_DATETIME))
        return [Quad(node, NamedNode(prov + "startedAtTime"), time)]

    store = OxigraphStore("http://amor-segb/events")
    for watched in (False, True):
        index = GraphIndex(store, tmp_path / f"graph-{watched}.sqlite3")
        draws = count_view_draws(index)
        index.build(0)
        assert len(draws) == 1  # drawn once built: the first visitor finds it drawn
        if watched:
            index.view(FIRST_VIEW)
            assert len(draws) == 1
        for number in range(10 * watched, 10 * watched + 3):  # each new activity enters the small first view
            store.apply(activity(number), number + 1)
            index.update(Delta.of(activity(number)), number + 1)
        assert len(draws) == (4 if watched else 1), watched
        if watched:
            assert index.view(FIRST_VIEW) == fresh(store, FIRST_VIEW)
            assert len(draws) == 4  # the request found it drawn
        index.close()
    store.close()


def test_a_request_while_the_keeper_draws_the_first_view_gets_the_one_before_and_its_through(tmp_path: Path) -> None:
    """While the keeper draws a changed first view, a request does not draw it too: it gets the view before, with
    the `through` that view includes; once the keeper is done, the new one and its `through`."""
    store = OxigraphStore("http://amor-segb/events")
    index = GraphIndex(store, tmp_path / "graph.sqlite3")
    graph = GraphService(Catalog(PACKAGE_ROOT / "sparql"), store, index, wait_ready=lambda _timeout: True)
    index.build(0)
    index.ready = True
    before = graph.graph(FIRST_VIEW)
    started, release = threading.Event(), threading.Event()
    draw = index._view

    def slow_for_the_keeper(connection: Any, request: GraphRequest) -> dict[str, object]:
        if threading.current_thread().name == "keeper":
            started.set()
            release.wait(30)
        return draw(connection, request)

    index._view = slow_for_the_keeper  # type: ignore[method-assign]
    robot = [Quad(NamedNode(f"{EX}robot/ari"), NamedNode(RDF_TYPE), NamedNode("http://kb.openrobots.org#Robot"))]
    store.apply(robot, 1)
    keeper = threading.Thread(target=index.update, args=(Delta.of(robot), 1), name="keeper")
    keeper.start()
    assert started.wait(30)
    assert graph.graph(FIRST_VIEW) == before
    release.set()
    keeper.join(30)
    after = graph.graph(FIRST_VIEW)
    assert after["through"] == 1 and after["nodes"] != before["nodes"]
    assert {key: value for key, value in after.items() if key != "through"} == fresh(store, FIRST_VIEW)
    index.close()
    store.close()


def test_a_neighbourhood_is_kept_while_other_robots_post_and_drawn_again_when_a_change_reaches_it(
    tmp_path: Path,
) -> None:
    """`/graph?focus=<robot>` depends only on the nodes within its depth: posts of another robot leave it kept,
    a post of its own robot (or a link into it, or a clearing) draws it again; kept or drawn, it equals the view
    of an index built afresh."""
    prov, segb = "http://www.w3.org/ns/prov#", "http://www.gsi.upm.es/ontologies/segb/ns#"

    def activity(robot: str, number: int) -> list[Quad]:
        node = NamedNode(f"{EX}activity/{robot}/{number}")
        return [
            Quad(node, NamedNode(prov + "startedAtTime"),
                 Literal(f"2026-03-10T00:00:{number % 60:02d}Z", datatype=NamedNode(XSD_DATETIME))),
            Quad(node, NamedNode(segb + "wasPerformedBy"), NamedNode(f"{EX}robot/{robot}")),
        ]  # fmt: skip

    store = OxigraphStore("http://amor-segb/events")
    store.apply([q for n in range(50) for robot in ("ari", "bo") for q in activity(robot, n)], 0)
    index = GraphIndex(store, tmp_path / "graph.sqlite3")
    index.build(0)
    drawn = count_draws(index)
    ari = GraphRequest(focus=f"{EX}robot/ari", depth=1)

    def step(quads: list[Quad] | None, through: int) -> int:
        """Apply a step (None: a clearing); how many times the neighbourhood was drawn to answer it."""
        if quads is None:
            store.clear(through)
            index.clear(through)
        else:
            store.apply(quads, through)
            index.update(Delta.of(quads), through)
        before = len(drawn)
        assert index.view(ari) == fresh(store, ari), through
        return len(drawn) - before

    try:
        assert step([], 0) == 1  # the first request draws it
        assert step(activity("bo", 100), 1) == 0  # another robot's post: kept
        assert step(activity("bo", 101), 2) == 0
        assert step(activity("ari", 100), 3) == 1  # its own robot's post reaches it
        assert step(activity("bo", 102), 4) == 0
        late_link = [Quad(NamedNode(f"{EX}activity/bo/0"), NamedNode(segb + "triggeredByActivity"),
                          NamedNode(f"{EX}activity/ari/0"))]  # fmt: skip
        assert step(late_link, 5) == 1  # a link into it from outside
        assert step(None, 6) == 1  # a clearing
        assert step(activity("ari", 200), 7) == 1
    finally:
        index.close()
        store.close()


def test_kept_neighbourhoods_under_concurrent_requests_and_updates_end_equal_a_fresh_index(tmp_path: Path) -> None:
    """Requests in a pool of threads (as the API serves them) ask several neighbourhoods while steps land:
    nothing fails, and once the steps stop every neighbourhood equals a fresh index's."""
    segb = "http://www.gsi.upm.es/ontologies/segb/ns#"
    robots = ["ari", "bo", "cy"]

    def activity(robot: str, number: int) -> list[Quad]:
        node = NamedNode(f"{EX}activity/{robot}/{number}")
        return [Quad(node, NamedNode(segb + "wasPerformedBy"), NamedNode(f"{EX}robot/{robot}"))]

    store = OxigraphStore("http://amor-segb/events")
    store.apply([q for n in range(20) for robot in robots for q in activity(robot, n)], 0)
    index = GraphIndex(store, tmp_path / "graph.sqlite3")
    index.build(0)
    requests = [GraphRequest(focus=f"{EX}robot/{robot}", depth=depth) for robot in robots for depth in (1, 2)]
    errors: list[BaseException] = []
    writing = threading.Event()

    def read() -> None:
        try:
            while writing.is_set():
                for request in requests:
                    index.view(request)
        except BaseException as error:  # reported below: a thread's exception would otherwise be lost
            errors.append(error)

    readers = [threading.Thread(target=read) for _ in range(6)]
    writing.set()
    try:
        for reader in readers:
            reader.start()
        for through in range(1, 61):
            quads = activity(robots[through % 3], 100 + through)
            store.apply(quads, through)
            index.update(Delta.of(quads), through)
        writing.clear()
        for reader in readers:
            reader.join()
        assert errors == []
        for request in requests:
            assert index.view(request) == fresh(store, request), request
    finally:
        writing.clear()
        index.close()
        store.close()


def test_a_neighbourhood_reaching_too_many_nodes_is_drawn_at_every_request(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What a kept view reaches is held in memory: past the bound, the view is drawn each time instead."""
    segb = "http://www.gsi.upm.es/ontologies/segb/ns#"
    monkeypatch.setattr(graph_index, "MAX_KEPT_REACH", 10)
    store = OxigraphStore("http://amor-segb/events")
    robot = NamedNode(f"{EX}robot/ari")
    store.apply([Quad(NamedNode(f"{EX}activity/{n}"), NamedNode(segb + "wasPerformedBy"), robot) for n in range(30)], 0)
    index = GraphIndex(store, tmp_path / "graph.sqlite3")
    index.build(0)
    drawn = count_draws(index)
    try:
        for request in (GraphRequest(focus=robot.value, depth=1), GraphRequest(focus=f"{EX}activity/0", depth=0)):
            drawn.clear()
            for _ in range(3):
                assert index.view(request) == fresh(store, request)
            assert len(drawn) == (3 if request.depth else 1), request  # 31 nodes reached, or only itself
    finally:
        index.close()
        store.close()
