"""The embedded store's cursor (how far the journal is applied), kept in memory beside its one quad: the same after
every kind of write and after the store is opened again, and alone in the store whatever a crash left."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import Literal, NamedNode, Quad
from pyoxigraph import Store as OxStore

from segb_server.backend.store.base import CURSOR_PREDICATE, CURSOR_SUBJECT
from segb_server.backend.store.oxigraph import CURSOR_GRAPH, XSD_INTEGER, OxigraphStore, live_directory

EX = "https://example.org/"


def quad(index: int) -> Quad:
    return Quad(NamedNode(f"{EX}s{index}"), NamedNode(f"{EX}p"), Literal(f"value {index}"))


def cursors_in(store: OxStore) -> list[int]:
    found = store.quads_for_pattern(CURSOR_SUBJECT, CURSOR_PREDICATE, None, CURSOR_GRAPH)
    return sorted(int(found_quad.object.value) for found_quad in found)


def test_the_cursor_follows_every_write_and_outlives_the_process(tmp_path: Path) -> None:
    path = tmp_path / "store"
    store = OxigraphStore("urn:segb:events", path)
    assert store.applied_through() is None
    store.apply([quad(1), quad(2)], through=3)
    store.apply([quad(3)], through=4)
    assert store.applied_through() == 4
    store.remove([quad(1)], through=5)  # an erasure: the store is written anew
    assert store.applied_through() == 5
    store.clear(through=6)
    assert store.applied_through() == 6 and store.count() == 0
    store.clear(through=6)  # the same cursor again: it stays
    assert store.applied_through() == 6
    store.apply([quad(4)], through=7)
    store.close()
    again = OxigraphStore("urn:segb:events", path)
    assert again.applied_through() == 7 and again.count() == 1
    again.close()
    raw = OxStore(str(live_directory(path)))
    assert cursors_in(raw) == [7]  # one quad: the ones before went as the cursor moved


def test_two_cursors_a_crash_left_are_read_as_the_latest_and_the_other_goes(tmp_path: Path) -> None:
    path = tmp_path / "store"
    OxigraphStore("urn:segb:events", path).close()
    raw = OxStore(str(live_directory(path)))
    for through in (8, 9):
        raw.add(Quad(CURSOR_SUBJECT, CURSOR_PREDICATE, Literal(str(through), datatype=XSD_INTEGER), CURSOR_GRAPH))
    raw.flush()
    del raw
    store = OxigraphStore("urn:segb:events", path)
    assert store.applied_through() == 9
    store.apply([quad(1)], through=10)
    store.close()
    assert cursors_in(OxStore(str(live_directory(path)))) == [10]
