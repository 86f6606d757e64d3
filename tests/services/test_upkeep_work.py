"""A post's upkeep does the same work whatever the robot did before: one robot whose history never stops growing
(a hub every post touches) must not make the views' work per post grow with it.

Work is counted, not timed: the store's queries and the rows they answer, and the SQLite virtual machine's
steps on each view's database, for the same kind of post after a short history and after one four times
longer. Two shapes of one robot: a receptionist meeting a new visitor each time (the robot's node gains
activities, people, shared events), and the emotion mirror talking to the same person all along (one pair of
robot and person whose aggregates grow).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from pyoxigraph import Quad, RdfFormat, parse
from rdflib import Graph

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.explain.service import TOLD_LITERALS
from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.graph_index import GraphIndex
from segb_server.backend.services.views.kept_queries.projection import KeptQueries
from segb_server.backend.services.views.kept_queries.rows import KeptRows
from segb_server.backend.services.views.seen_terms import SeenTerms
from segb_server.backend.services.views.shape_view import ShapeFindings
from segb_server.backend.store.base import QueryResult
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from segb_server.examples.receptionist import log_visit, receptionist

T0 = datetime(2026, 1, 5, 8, 0, tzinfo=UTC)
# Posts before the measured ones: past a few hundred, so the first view of the graph (its 1,500 first nodes, which
# every post's new people may enter) is full after both histories, and four times longer.
SHORT, LONG = 250, 1000
MEASURED = 6  # posts measured after each history
STEPS_PER_TICK = 100  # SQLite virtual machine steps per progress tick
# What a post may cost more after a four times longer history: a few more rows where a post joins a name or a
# count that is already there, never a factor of the history.
ALLOWED = 1.3


class CountingStore(OxigraphStore):
    """The embedded store, counting the queries the views ask and the rows it answers them."""

    def __init__(self, path: Path) -> None:
        super().__init__("http://amor-segb/events", path)
        self.queries = 0
        self.rows = 0

    def query(self, sparql: str, bindings: Any = None, timeout: float | None = None) -> QueryResult:
        self.queries += 1
        self.rows += len(list(super().query(sparql, bindings, timeout)))  # type: ignore[arg-type]
        return super().query(sparql, bindings, timeout)  # asked again: the views read their own answer


@dataclass
class Work:
    queries: int = 0
    rows: int = 0
    steps: dict[str, int] = field(default_factory=dict)  # view → SQLite steps (in ticks of STEPS_PER_TICK)


@dataclass
class Views:
    store: CountingStore
    kept: list[Any]
    ticks: dict[str, int]
    seen: SeenTerms | None  # the IRIs the store holds, which tell a post's fresh ones (as the server's keeper does)
    applied: int = 0

    def history(self, posts: Sequence[Sequence[Quad]]) -> None:
        """The robot's history in the store, and every view built from it."""
        for quads in posts:
            self.applied += 1
            self.store.apply(quads, self.applied)
        if self.seen is not None:
            self.seen.build(self.store, self.applied)
        for view in self.kept:
            view.build(self.applied)

    def post(self, quads: Sequence[Quad]) -> None:
        self.applied += 1
        self.store.apply(quads, self.applied)
        fresh = frozenset[str]() if self.seen is None else self.seen.admit(quads, self.applied, self.applied)
        delta = Delta.of(quads, fresh)
        for view in self.kept:
            view.update(delta, self.applied)

    def measure(self, posts: Sequence[Sequence[Quad]]) -> Work:
        self.store.queries = self.store.rows = 0
        for name in self.ticks:
            self.ticks[name] = 0
        for quads in posts:
            self.post(quads)
        return Work(self.store.queries, self.store.rows, dict(self.ticks))


def kept_views(tmp_path: Path, counting: type[CountingStore] = CountingStore, *, registry: bool = True) -> Views:
    """Every view a server keeps, as `build_services` makes them: the reports' rows, the timeline's kinds, the
    graph index, the SPARQL rules' findings and the SHACL rules' findings; with `registry`, told which of a post's
    IRIs are fresh, as the server's views are."""
    store = counting(tmp_path / "store")
    catalog = Catalog(PACKAGE_ROOT / "sparql")
    rules = RuleCatalog(PACKAGE_ROOT / "rules")
    reports = KeptQueries(store, KeptRows(tmp_path / "reports.sqlite3"))
    for query in catalog.under("reports"):
        reports.add(query)
    timeline = KeptQueries(store, KeptRows(tmp_path / "timeline.sqlite3"))
    for query in catalog.under("timeline"):
        timeline.add(query)
    findings = KeptQueries(store, KeptRows(tmp_path / "findings.sqlite3"))
    for rule in rules.sparql():
        assert rule.query is not None
        findings.add(rule.query)
    shapes = ShapeFindings(store, [ShapeRule(rule) for rule in rules.shapes()], tmp_path / "shape-findings.sqlite3")
    index = GraphIndex(store, tmp_path / "graph.sqlite3", detail_literals=TOLD_LITERALS)
    databases = {"reports": reports.rows.db, "timeline": timeline.rows.db, "findings": findings.rows.db,
                 "shapes": shapes.db, "graph": index.db}  # fmt: skip
    ticks = dict.fromkeys(databases, 0)
    for name, database in databases.items():
        database.writer().set_progress_handler(_counter(ticks, name), STEPS_PER_TICK)
    seen = SeenTerms(tmp_path / "seen-terms.sqlite3") if registry else None
    return Views(store, [*reports.views(), *timeline.views(), index, *findings.views(), shapes], ticks, seen)


def _counter(ticks: dict[str, int], name: str) -> Callable[[], int]:
    def tick() -> int:
        ticks[name] += 1
        return 0  # go on

    return tick


def receptionist_posts(count: int) -> list[list[Quad]]:
    """`count` visits of one robot, each post what that visit added (a new visitor each time)."""
    logger = receptionist()
    seen: set[tuple[Any, ...]] = set()
    posts = [_new(logger.graph, seen)]
    for index in range(count):
        logger.graph = Graph()  # each visit logged apart: what it adds is then a small graph to read
        log_visit(logger, index, T0 + timedelta(seconds=7 * index))
        posts.append(_new(logger.graph, seen))
    return posts


def mirror_posts(count: int) -> list[list[Quad]]:
    """`count` interactions of the emotion mirror with the same person, each interaction's three events one post."""
    config = RobotConfig(robot_id="mirror", base_namespace="https://example.org/segb/robots/mirror/v1/")
    mission = EmotionMirrorMission.start(config, human_id="maria", human_name="Maria")
    seen: set[tuple[Any, ...]] = set()
    posts = [_new(mission.logger.graph, seen)]
    expressions = ["happy", "sad", "angry", "surprised"]
    for index in range(count):
        mission.logger.graph = Graph()
        at = T0 + timedelta(seconds=20 * index)
        mission.on_face_expression(expressions[index % len(expressions)], at)
        exchange = mission.on_user_utterance(f"Utterance {index}", at + timedelta(seconds=1))
        mission.respond(exchange, at + timedelta(seconds=3))
        posts.append(_new(mission.logger.graph, seen))
    return posts


def _new(graph: Graph, seen: set[tuple[Any, ...]]) -> list[Quad]:
    """The triples of `graph` not posted before, as a post of the robot's client would add them."""
    new = Graph()
    for triple in graph:
        if triple not in seen:
            seen.add(triple)
            new.add(triple)
    return list(parse(new.serialize(format="nt").encode(), RdfFormat.N_TRIPLES))


@pytest.mark.slow  # histories of 250 and 1,000 posts, twice
@pytest.mark.parametrize("registry", [True, False], ids=["fresh-terms-known", "every-join-asked"])
@pytest.mark.parametrize("shape", [receptionist_posts, mirror_posts], ids=["new-visitors", "same-person"])
def test_a_posts_upkeep_work_does_not_grow_with_the_robots_history(
    tmp_path: Path, shape: Callable[[int], list[list[Quad]]], registry: bool
) -> None:
    # Both ways a view finds what a post changes: joins from the post's own resources followed among its triples
    # (the server's), and every join asked of the store (a view catching up from the journal).
    posts = shape(LONG + 2 * MEASURED)
    short = kept_views(tmp_path / "short", registry=registry)
    long = kept_views(tmp_path / "long", registry=registry)
    short.history(posts[: 1 + SHORT])
    long.history(posts[: 1 + LONG])
    # The same kind of post on both: the next ones after each history.
    after_short = short.measure(posts[1 + SHORT : 1 + SHORT + MEASURED])
    after_long = long.measure(posts[1 + LONG : 1 + LONG + MEASURED])
    assert after_long.queries <= after_short.queries, (after_short, after_long)
    assert after_long.rows <= after_short.rows * ALLOWED, (after_short, after_long)
    for view, steps in after_short.steps.items():
        assert after_long.steps[view] <= steps * ALLOWED + 2, (view, after_short, after_long)


class RecordingStore(CountingStore):
    """The counting store, keeping the texts of the queries asked too."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.texts: list[str] = []

    def query(self, sparql: str, bindings: Any = None, timeout: float | None = None) -> QueryResult:
        self.texts.append(sparql)
        return super().query(sparql, bindings, timeout)


def test_a_post_of_new_resources_asks_the_store_for_its_rows_only(tmp_path: Path) -> None:
    # Which rows a visit changes and which filter pairs it adds are joins from the visit's own resources (a new
    # visitor, activity, message, event): followed among the post's triples, they ask the store nothing. What the
    # store is still asked: each view's rows for those keys, and the SHACL shapes' targets.
    posts = receptionist_posts(40)
    asked = {}
    for registry in (True, False):
        views = kept_views(tmp_path / str(registry), RecordingStore, registry=registry)
        store = views.store
        assert isinstance(store, RecordingStore)
        views.history(posts[:30])
        store.texts.clear()
        for post in posts[30:]:
            views.post(post)
        asked[registry] = list(store.texts)
    joins = [text for text in asked[True] if text.startswith("SELECT DISTINCT")]
    assert not joins, joins[:3]
    assert [text for text in asked[False] if text.startswith("SELECT DISTINCT")], "no join was asked without them"
    assert len(asked[True]) < len(asked[False]) * 0.7, (len(asked[True]), len(asked[False]))


def test_a_batch_asks_each_filter_question_once_for_every_view(tmp_path: Path) -> None:
    # The reports and the timeline's kinds filter by the same robot and human: the pairs a batch adds to those
    # filters are the same questions for each of them, asked of the store once.
    views = kept_views(tmp_path, RecordingStore, registry=False)
    store = views.store
    assert isinstance(store, RecordingStore)
    posts = receptionist_posts(12)
    views.history(posts[:10])
    store.texts.clear()
    views.post([quad for post in posts[10:] for quad in post])
    filters = [text for text in store.texts if "?param_" in text.partition("WHERE")[0]]
    assert filters, "the batch asked no filter's pairs"
    assert len(filters) == len(set(filters)), [text[:200] for text in filters if filters.count(text) > 1][:3]


def test_a_shapes_targets_among_a_batchs_nodes_are_one_row_each(tmp_path: Path) -> None:
    # Asking whether a node is a target must not read everything that makes it one: a SPARQL target
    # (`?this ?p ?o`) joined would answer a row per statement of the node, and a hub's statements never stop
    # growing.
    store = CountingStore(tmp_path / "store")
    hub = "https://example.org/robots/hub"
    lines = [f'<{hub}> <https://example.org/said> "line {n}" .' for n in range(500)]
    lines.append(f"<{hub}> <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> <https://example.org/Robot> .")
    store.apply(list(parse("\n".join(lines).encode(), RdfFormat.N_TRIPLES)), 1)
    rules = {rule.id: ShapeRule(rule) for rule in RuleCatalog(PACKAGE_ROOT / "rules").shapes()}
    store.queries = store.rows = 0
    targets = rules["subject-without-type"].targets(store, [f"<{hub}>", "<https://example.org/nothing>"])
    assert {node for nodes in targets.values() for node in nodes} == {f"<{hub}>"}
    assert store.rows <= store.queries, (store.queries, store.rows)


def _asked_by(view: Any, texts: Sequence[str]) -> int:
    """How many of `texts` are `view`'s own query (its rows for some keys): the same text up to its WHERE."""
    head = view.text.partition("WHERE")[0]
    return sum(1 for text in texts if text.partition("WHERE")[0] == head)


def test_a_kind_whose_rows_a_visit_cannot_have_asks_the_store_nothing(tmp_path: Path) -> None:
    # A receptionist's visit logs a listening and a response activity and their messages: no detection of a human
    # or reading of an emotion, no activity of another kind, no observation that is not a message. The timeline's
    # perceptions need a detection's or a reading's type (`FILTER (?perceptionClass IN (…))`), its other activities
    # and its observations exclude what the visit's resources are (`FILTER NOT EXISTS { ?activity a ?moreSpecific
    # … }`, `FILTER NOT EXISTS { ?observation a schema:Message }`): told among the visit's own triples, which are
    # all there is about its new resources, those kinds have no row to ask the store for.
    views = kept_views(tmp_path, RecordingStore)
    store = views.store
    assert isinstance(store, RecordingStore)
    posts = receptionist_posts(12)
    views.history(posts[:10])
    store.texts.clear()
    for post in posts[10:]:
        views.post(post)
    asked = {view.name: _asked_by(view, store.texts) for view in views.kept if hasattr(view, "text")}
    assert asked["timeline/perception"] == asked["timeline/activity"] == asked["timeline/observation"] == 0, asked
    # The kinds a visit has rows of still ask for them.
    assert asked["timeline/listening"] > 0 and asked["timeline/response"] > 0 and asked["timeline/message"] > 0, asked
