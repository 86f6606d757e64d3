"""The views' keeper rests after each batch so requests keep their share of the cores, but never so long that a
step applied meanwhile waits past its start-by time (its rows are due in the reports within a second)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

from pyoxigraph import DefaultGraph, NamedNode, Quad

from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.keeper import MAX_REST_SECONDS, ViewKeeper
from segb_server.backend.services.views.lanes import SMALL_BATCH_TRIPLES
from segb_server.backend.services.views.preparing import RETRY_BUILD_SECONDS
from segb_server.backend.services.views.steps import START_WITHIN_SECONDS
from segb_server.backend.services.writing.applier import Applied, quads_of
from segb_server.backend.services.writing.journal import Journal, JournalEntry
from segb_server.backend.state.database import StateUnavailable
from segb_server.backend.state.sqlite import SqliteDatabase
from segb_server.backend.store.oxigraph import OxigraphStore

BATCH_SECONDS = 0.5  # longer than a step may wait, and than the longest rest


class RecordingView:
    """A view that records its updates (through, began, ended) and builds; each update takes `seconds`, or fails
    with a bug (`failing`) rather than an outage."""

    def __init__(self, name: str, seconds: float = 0.0, failing: bool = False) -> None:
        self.name = name
        self.seconds = seconds
        self.failing = failing
        self.ready = False
        self.updates: list[tuple[int, float, float]] = []
        self.built: list[int] = []
        self.updated = threading.Condition()
        self.began = threading.Event()  # an update is under way

    def stored_through(self) -> int | None:
        return 0

    def build(self, through: int) -> None:
        self.built.append(through)

    def update(self, delta: Delta, through: int) -> None:
        if self.failing:
            raise RuntimeError("a view's bug")
        began = time.monotonic()
        self.began.set()
        time.sleep(self.seconds)  # the update's own work
        with self.updated:
            self.updates.append((through, began, time.monotonic()))
            self.updated.notify_all()

    def clear(self, through: int) -> None:
        pass

    def follow(self) -> int | None:
        return 0

    def prepared(self) -> None:
        pass

    def wait_for_updates(self, count: int) -> None:
        with self.updated:
            assert self.updated.wait_for(lambda: len(self.updates) >= count, timeout=10)


def store_through_3() -> OxigraphStore:
    """A store holding one triple, applied through journal entry 3."""
    store = OxigraphStore("urn:x:graph")
    store.apply([Quad(NamedNode("urn:x:s"), NamedNode("urn:x:p"), NamedNode("urn:x:o"), DefaultGraph())], through=3)
    return store


def keeper_of(tmp_path: Path, *views: RecordingView) -> ViewKeeper:
    """A keeper of `views` over an empty store, its journal in `tmp_path`."""
    return ViewKeeper(OxigraphStore("urn:x:graph"), Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), list(views))


def step(sequence: int) -> Applied:
    return Applied([JournalEntry(sequence, "post", b"")], [], cleared=False)


def test_a_rest_is_cut_short_for_a_step_that_waited_through_a_slow_batch_and_kept_otherwise(tmp_path: Path) -> None:
    assert BATCH_SECONDS > START_WITHIN_SECONDS and BATCH_SECONDS > MAX_REST_SECONDS
    view = RecordingView("slow", seconds=BATCH_SECONDS)
    projector = keeper_of(tmp_path, view)
    projector.start()
    try:
        projector.on_applied(step(1))
        assert view.began.wait(timeout=10)
        projector.on_applied(step(2))  # queued while the first batch runs: by its end it waited past its time
        view.wait_for_updates(2)
        (_, _, first_ended), (through, second_began, second_ended) = view.updates
        assert through == 2
        assert second_began - first_ended < 0.15  # no rest: a rest would have held it MAX_REST_SECONDS more

        time.sleep(0.05)
        projector.on_applied(step(3))  # queued during the rest, with time to spare: the rest is kept
        view.wait_for_updates(3)
        third_began = view.updates[2][1]
        assert third_began - second_ended >= MAX_REST_SECONDS - 0.02
        assert projector.progress.wait_for(3, timeout=5)
    finally:
        projector.stop()


def test_a_view_whose_catch_up_fails_is_built_again_and_the_others_are_kept(tmp_path: Path) -> None:
    store = store_through_3()
    broken, kept = RecordingView("broken", failing=True), RecordingView("kept")
    projector = ViewKeeper(store, Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [broken, kept])
    projector.start()
    try:
        assert projector.progress.wait_for(3, timeout=5)  # the views' thread lives on, and every view is ready
        assert broken.built == [3]
        assert [through for through, _, _ in kept.updates] == [3] and kept.built == []
    finally:
        projector.stop()


def test_steps_queued_past_the_bound_wait_without_their_triples_and_every_triple_reaches_the_views(
    tmp_path: Path,
) -> None:
    """A view far behind (a burst of posts, a slow store) must not make the queue hold every post's triples:
    past the bound, steps wait as journal numbers and their triples are read back when their turn comes."""
    journal = Journal(SqliteDatabase(tmp_path / "journal.sqlite3"))
    posts = [
        [
            Quad(NamedNode(f"urn:x:post{n}"), NamedNode("urn:x:p"), NamedNode(f"urn:x:o{k}"), DefaultGraph())
            for k in range(10)
        ]
        for n in range(60)
    ]
    journal.append_posts([post_entry(quads, "test", None, "0" * 64) for quads in posts])
    view = CollectingView("slow", seconds=0.05)
    keeper = ViewKeeper(OxigraphStore("urn:x:graph"), journal, [view], max_queued_triples=100)
    keeper.start()
    try:
        for entry in journal.entries_after(0, 60):
            keeper.on_applied(Applied([entry], quads_of([entry]), cleared=False))
        assert keeper.progress.wait_for(60, timeout=20)
        assert keeper.most_queued_triples <= 100
        assert sorted(view.triples) == sorted(
            quad.subject.value + " " + quad.object.value for post in posts for quad in post
        )
    finally:
        keeper.stop()


class CollectingView(RecordingView):
    """Keeps every triple it is given."""

    def __init__(self, name: str, seconds: float = 0.0) -> None:
        super().__init__(name, seconds=seconds)
        self.triples: list[str] = []

    def update(self, delta: Delta, through: int) -> None:
        self.triples += [quad.subject.value + " " + quad.object.value for quad in delta.quads]
        super().update(delta, through)


class BlockedBuild(RecordingView):
    """A view whose build waits for `release`: the views are being built meanwhile."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.release = threading.Event()

    def stored_through(self) -> int | None:
        return None  # never built: built at start

    def build(self, through: int) -> None:
        assert self.release.wait(timeout=10)
        super().build(through)


def test_the_views_being_built_are_named_while_the_store_holds_entries_they_miss(tmp_path: Path) -> None:
    """What readiness reports as `views_building` (and what tests settle on): the views not built yet, but only
    while there is something they miss (an empty store has nothing to build)."""
    slow, quick = BlockedBuild("slow"), RecordingView("quick")
    keeper = ViewKeeper(
        OxigraphStore("urn:x:graph"), Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [quick, slow]
    )
    assert keeper.progress.building(applied=0) == []
    assert keeper.progress.building(applied=3) == ["quick", "slow"]
    keeper.start()
    try:
        deadline = time.monotonic() + 10
        while not quick.ready:  # built in order: the quick one first, then the slow one waits
            assert time.monotonic() < deadline
            time.sleep(0.01)
        assert keeper.progress.building(applied=3) == ["slow"]
        slow.release.set()
        while keeper.progress.building(applied=3):
            assert time.monotonic() < deadline, keeper.progress.building(applied=3)
            time.sleep(0.01)
        assert slow.built and slow.ready and quick.ready
    finally:
        slow.release.set()
        keeper.stop()


class FailingBuild(RecordingView):
    """A view never built before whose first `failures` builds raise a bug (not an outage)."""

    def __init__(self, name: str, failures: int) -> None:
        super().__init__(name)
        self.failures = failures

    def stored_through(self) -> int | None:
        return None if not self.built else self.built[-1]

    def build(self, through: int) -> None:
        if self.failures:
            self.failures -= 1
            raise RuntimeError("a view's bug while it is built")
        super().build(through)


def test_a_view_whose_build_fails_is_set_aside_the_others_kept_current_and_it_is_built_again(tmp_path: Path) -> None:
    """A build failing on its own (a bug, its query refused) must neither end the views' thread nor hold the
    other views back (every report would stay behind for good): they are built and kept current, the failing
    one is built again every RETRY_BUILD_SECONDS, and meanwhile the error is what readiness tells."""
    store = store_through_3()
    failing, after = FailingBuild("failing", failures=2), FailingBuild("after", failures=0)
    keeper = ViewKeeper(store, Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [failing, after])
    keeper.start()
    try:
        assert keeper.progress.wait_for(3, timeout=10)  # every view but the one set aside
        assert after.ready and not failing.ready and after.built == [3] and failing.built == []
        assert keeper.progress.building(applied=3) == ["failing"]
        assert keeper.last_error == "failing: a view's bug while it is built"
        keeper.on_applied(step(4))  # kept by the others meanwhile
        after.wait_for_updates(1)
        assert [through for through, _, _ in after.updates] == [4] and failing.updates == []
        deadline = time.monotonic() + 4 * RETRY_BUILD_SECONDS
        while keeper.progress.building(applied=4):
            assert time.monotonic() < deadline, keeper.progress.building(applied=4)
            time.sleep(0.01)
        assert failing.ready and failing.built in ([3], [4]) and failing.failures == 0 and keeper.last_error is None
        keeper.on_applied(step(5))
        failing.wait_for_updates(1)
        assert keeper.progress.wait_for(5, timeout=10)
    finally:
        keeper.stop()


def test_a_view_whose_rebuild_after_a_failed_update_fails_is_set_aside_and_built_again(tmp_path: Path) -> None:
    """An update failing with a bug has the views built again; when that build fails too, the view is set
    aside and built again later, the views' thread living on."""
    view = FailingBuild("broken", failures=1)
    view.built, view.failing = [0], True  # built before; every update fails
    keeper = keeper_of(tmp_path, view)
    keeper.start()
    try:
        keeper.on_applied(step(1))
        assert keeper.progress.wait_for(1, timeout=10)
        deadline = time.monotonic() + 4 * RETRY_BUILD_SECONDS
        while keeper.progress.building(applied=1):
            assert time.monotonic() < deadline, keeper.last_error
            time.sleep(0.01)
        assert view.built == [0, 1] and view.failures == 0 and view.ready and keeper.last_error is None
    finally:
        keeper.stop()


class AwayOnce(FailingBuild):
    """A view whose first build finds the views' storage away (an outage: every view waits, tried again)."""

    def build(self, through: int) -> None:
        if self.failures:
            self.failures -= 1
            raise StateUnavailable("the views' storage is away")
        RecordingView.build(self, through)


def test_a_view_set_aside_and_built_when_an_outage_has_every_view_tried_again_is_kept_current(tmp_path: Path) -> None:
    """A view set aside at start and built at the next try (an outage of another view's storage had them all
    tried again) is kept current like the others from then on, and no error is told any more."""
    store = store_through_3()
    failing, away = FailingBuild("failing", failures=1), AwayOnce("away", failures=1)
    keeper = ViewKeeper(store, Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [failing, away])
    keeper.start()
    try:
        deadline = time.monotonic() + 4 * RETRY_BUILD_SECONDS
        while not (failing.ready and away.ready):
            assert time.monotonic() < deadline, keeper.last_error
            time.sleep(0.01)
        assert keeper.last_error is None and keeper.progress.building(applied=3) == []
        keeper.on_applied(step(4))
        failing.wait_for_updates(1)
        assert keeper.progress.wait_for(4, timeout=10)
        assert failing.built == [3] and away.built == [3]  # built once: put back, not built again as set aside
    finally:
        keeper.stop()


class GatedView(RecordingView):
    """A view whose update waits for `release` (a view busy with a large import)."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.release = threading.Event()

    def update(self, delta: Delta, through: int) -> None:
        self.began.set()
        assert self.release.wait(timeout=20)
        super().update(delta, through)


def test_a_view_busy_with_a_large_batch_holds_no_other_view_back(tmp_path: Path) -> None:
    """Each view follows the journal at its own pace: while one is busy with an import, the others take the posts
    that came after it, their lag told apart from its own; the busy one then takes every batch it missed."""
    busy, reports = GatedView("graph"), CollectingView("reports/conversations")
    keeper = ViewKeeper(
        OxigraphStore("urn:x:graph"), Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [busy, reports]
    )
    keeper.start()
    try:
        keeper.on_applied(step(1))  # the import
        assert busy.began.wait(timeout=10)
        for sequence in (2, 3, 4):  # posts after it
            keeper.on_applied(step(sequence))
        deadline = time.monotonic() + 5
        while keeper.progress.view_through("reports/conversations") < 4:
            assert time.monotonic() < deadline, reports.updates
            time.sleep(0.01)
        assert keeper.progress.view_through("graph") == 0 and keeper.progress.through == 0 and not busy.updates
        lags = keeper.progress.view_lags(applied=4)
        assert set(lags) == {"graph"} and lags["graph"][0] == 4
        assert not keeper.progress.wait_for(4, timeout=0.1)  # every view's: the busy one's too
        busy.release.set()
        assert keeper.progress.wait_for(4, timeout=10)
        assert [through for through, _, _ in busy.updates][-1] == 4 and len(busy.updates) <= 2  # what it missed, as one
    finally:
        busy.release.set()
        keeper.stop()


class AheadView(RecordingView):
    """A view whose rows are read key by key from the store (`GoesAhead`): its update of a large batch runs in
    parts, held until released, and records what was taken ahead of it."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.release = threading.Event()
        self.ahead: list[int] = []
        self.position: list[int] = []  # where each update in parts left the view

    def update_ahead(self, delta: Delta, through: int) -> None:
        with self.updated:
            self.ahead.append(through)
            self.updated.notify_all()

    def update_in_parts(self, delta: Delta, through: int, between: Callable[[], int]) -> None:
        self.began.set()
        while not self.release.wait(timeout=0.01):
            between()  # a part of its keys done: the posts behind it go ahead
        self.position.append(max(through, between()))
        super().update(delta, through)


def large_step(sequence: int) -> Applied:
    """An import: a step of more triples than a small batch holds."""
    quads = [Quad(NamedNode(f"urn:x:s{n}"), NamedNode("urn:x:p"), NamedNode("urn:x:o"), DefaultGraph())
             for n in range(SMALL_BATCH_TRIPLES + 1)]  # fmt: skip
    return Applied([JournalEntry(sequence, "post", b"")], quads, cleared=False)


def test_posts_go_ahead_of_a_large_batch_in_a_view_that_reads_its_keys_from_the_store(tmp_path: Path) -> None:
    """A report busy with an import takes the posts that came after it ahead of it: their rows need not wait for
    the import's. Its position moves past them only once the import is taken in too."""
    report = AheadView("reports/conversations")
    keeper = keeper_of(tmp_path, report)
    keeper.start()
    try:
        keeper.on_applied(large_step(1))
        assert report.began.wait(timeout=10)
        for sequence in (2, 3, 4):  # posts after it, while it is still taking the import in
            keeper.on_applied(step(sequence))
        with report.updated:
            assert report.updated.wait_for(lambda: report.ahead and report.ahead[-1] == 4, timeout=10), report.ahead
        assert keeper.progress.view_through("reports/conversations") == 0  # its lag still says the import
        assert not report.updates  # the import not done
        report.release.set()
        assert keeper.progress.wait_for(4, timeout=10)
        assert report.position == [4] and [through for through, _, _ in report.updates] == [1]
        assert sorted(report.ahead) == report.ahead and set(report.ahead) <= {2, 3, 4}
    finally:
        report.release.set()
        keeper.stop()


def test_a_view_that_follows_its_batches_in_order_takes_no_post_ahead_of_a_large_batch(tmp_path: Path) -> None:
    """The graph index and the SHACL findings follow the triples of each batch: the posts wait behind the import."""
    graph = GatedView("graph")
    keeper = keeper_of(tmp_path, graph)
    keeper.start()
    try:
        keeper.on_applied(large_step(1))
        assert graph.began.wait(timeout=10)
        keeper.on_applied(step(2))
        time.sleep(0.3)
        assert not graph.updates
        graph.release.set()
        assert keeper.progress.wait_for(2, timeout=10)
        assert [through for through, _, _ in graph.updates] == [1, 2]
    finally:
        graph.release.set()
        keeper.stop()
