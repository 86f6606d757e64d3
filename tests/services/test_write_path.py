"""The write path as one component (journal → applier → views' keeper), on a memory server: what posts and readers
wait for, how far behind each stage is, and what is on its way to the views while they lag."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.writing.write_path import Lag, WritePath
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings

EX = "https://example.org/"


class GatedView:
    """A view whose updates wait at a gate (a view that has fallen behind), counting the triples it was given."""

    name = "gated"

    def __init__(self) -> None:
        self.ready = False
        self.gate = threading.Event()
        self.gate.set()
        self.through: int | None = None
        self.triples = 0

    def stored_through(self) -> int | None:
        return self.through

    def build(self, through: int) -> None:
        self.through = through

    def update(self, delta: Delta, through: int) -> None:
        assert self.gate.wait(timeout=30)
        self.triples += len(delta.quads)
        self.through = through

    def clear(self, through: int) -> None:
        self.triples, self.through = 0, through

    def follow(self) -> int | None:
        return self.through

    def prepared(self) -> None:
        pass


@pytest.fixture
def view() -> GatedView:
    return GatedView()


@pytest.fixture
def path(view: GatedView) -> Iterator[WritePath]:
    opened = WritePath.open(make_settings(store="memory"), OxigraphStore("urn:x:events"), [view])
    opened.start()
    yield opened
    view.gate.set()
    opened.close()


def write(path: WritePath, value: str) -> int:
    """Record a post of one triple in the journal, and tell the applier; its journal entry."""
    quads = [Quad(NamedNode(EX + value), NamedNode(EX + "p"), Literal(value))]
    (receipt,) = path.journal.append_posts([post_entry(quads, "ari", None, "0" * 64)])
    path.entries_written()
    return receipt.sequence  # type: ignore[union-attr]


def test_a_post_is_applied_then_viewed_and_nothing_is_behind(path: WritePath, view: GatedView) -> None:
    entry = write(path, "a")
    assert path.wait_applied(entry, timeout=10) and path.wait_viewed(entry, timeout=10)
    assert (path.applied, path.backlog(), view.triples) == (1, 0, 1)
    assert path.lag() == Lag(0, 0.0, 0, 0.0)
    assert path.on_the_way(limit=10) == []


def test_while_the_views_lag_the_triples_on_their_way_stand_in_for_them(path: WritePath, view: GatedView) -> None:
    assert path.wait_viewed(write(path, "a"), timeout=10)
    view.gate.clear()  # the views fall behind from here
    first, second = write(path, "b"), write(path, "c")
    assert path.wait_applied(second, timeout=10)
    assert not path.wait_viewed(first, timeout=0.05)
    lag = path.lag()
    assert (lag.apply_entries, lag.views_entries) == (0, 2) and lag.views_seconds >= 0
    on_the_way = path.on_the_way(limit=10)
    assert on_the_way is not None and sorted(str(q.object) for q in on_the_way) == ['"b"', '"c"']
    assert path.on_the_way(limit=1) is None  # more entries than asked for: they cannot stand in

    view.gate.set()
    assert path.wait_viewed(second, timeout=10)
    assert view.triples == 3 and path.lag().views_entries == 0


def test_a_post_applied_in_the_calling_thread_needs_no_wait() -> None:
    path = WritePath.open(make_settings(store="memory"), OxigraphStore("urn:x:events"), [])
    try:
        quads = [Quad(NamedNode(EX + "a"), NamedNode(EX + "p"), Literal("a"))]
        path.journal.append_posts([post_entry(quads, "ari", None, "0" * 64)])
        assert path.backlog() == 1
        path.apply_now()
        assert (path.applied, path.backlog()) == (1, 0)
    finally:
        path.close()
