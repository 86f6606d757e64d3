"""The views' keeper rests after each batch so requests keep their share of the cores, but never so long that a
step applied meanwhile waits past its start-by time (its rows are due in the reports within a second)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

from pyoxigraph import DefaultGraph, NamedNode, Quad

from segb_server.backend.services.ingest.applier import Applied
from segb_server.backend.services.ingest.journal import Journal, JournalEntry
from segb_server.backend.services.views.projector import (
    MAX_REST_SECONDS,
    START_WITHIN_SECONDS,
    Projector,
)
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

    def stored_through(self) -> int | None:
        return 0

    def build(self, through: int) -> None:
        self.built.append(through)

    def update(self, quads: list, through: int) -> None:  # type: ignore[type-arg]
        if self.failing:
            raise RuntimeError("a view's bug")
        began = time.monotonic()
        time.sleep(self.seconds)
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


def step(sequence: int) -> Applied:
    return Applied([JournalEntry(sequence, "post", b"")], [], cleared=False)


def test_a_rest_is_cut_short_for_a_step_that_waited_through_a_slow_batch_and_kept_otherwise(tmp_path: Path) -> None:
    assert BATCH_SECONDS > START_WITHIN_SECONDS and BATCH_SECONDS > MAX_REST_SECONDS
    view = RecordingView("slow", seconds=BATCH_SECONDS)
    projector = Projector(OxigraphStore("urn:x:graph"), Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [view])
    projector.start()
    try:
        projector.on_applied(step(1))
        time.sleep(0.05)
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
        assert projector.wait_for(3, timeout=5)
    finally:
        projector.stop()


def test_a_view_whose_catch_up_fails_is_built_again_and_the_others_are_kept(tmp_path: Path) -> None:
    store = OxigraphStore("urn:x:graph")
    store.apply([Quad(NamedNode("urn:x:s"), NamedNode("urn:x:p"), NamedNode("urn:x:o"), DefaultGraph())], through=3)
    broken, kept = RecordingView("broken", failing=True), RecordingView("kept")
    projector = Projector(store, Journal(SqliteDatabase(tmp_path / "journal.sqlite3")), [broken, kept])
    projector.start()
    try:
        assert projector.wait_for(3, timeout=5)  # the views' thread lives on, and every view is ready
        assert broken.built == [3]
        assert [through for through, _, _ in kept.updates] == [3] and kept.built == []
    finally:
        projector.stop()
