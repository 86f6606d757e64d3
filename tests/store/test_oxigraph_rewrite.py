"""The embedded store written anew without erased triples: the copy gets a directory of its own, named by a
pointer file, so a reader still holding the old store can never touch the copy's files; what a crash leaves
is tidied at the next start."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import DefaultGraph, Literal, NamedNode, Quad

from segb_server.backend.store.oxigraph import GENERATION, POINTER, REWRITING, OxigraphStore

EX = "https://example.org/rewrite/"


def quad(n: int) -> Quad:
    return Quad(NamedNode(f"{EX}s{n}"), NamedNode(f"{EX}p"), Literal(f"text {n}"), DefaultGraph())


def texts(store: OxigraphStore) -> set[str]:
    return {str(row["o"].value) for row in store.query("SELECT ?o WHERE { ?s ?p ?o }")}  # type: ignore[union-attr, index]


def test_a_rewrite_while_a_reader_holds_the_old_store_leaves_the_copy_whole(tmp_path: Path) -> None:
    path = tmp_path / "oxigraph"
    store = OxigraphStore("urn:x:graph", path)
    store.apply([quad(n) for n in range(2000)], through=1)
    reading = iter(store.query("SELECT ?o WHERE { ?s ?p ?o }"))  # type: ignore[call-overload]
    next(reading)  # a reader in the middle of the old store's answer

    store.remove([quad(n) for n in range(0, 2000, 2)], through=2)
    store.remove([quad(1)], through=3)  # a second erasure in the same process
    assert len(list(reading)) == 1999  # the reader finishes on the old store, undisturbed
    del reading

    live = store.live
    assert live is not None and live.name.startswith(f"oxigraph{GENERATION}")
    assert not path.exists()  # the first directory, with the erased text in its files, is gone
    assert (tmp_path / f"oxigraph{POINTER}").read_text() == live.name
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(f"oxigraph{GENERATION}")] == [live.name]
    assert texts(store) == {f"text {n}" for n in range(3, 2000, 2)} and store.applied_through() == 3
    store.close()
    del store

    again = OxigraphStore("urn:x:graph", path)  # a restart opens the copy the pointer names
    assert again.live == live and again.applied_through() == 3 and len(texts(again)) == 999
    again.close()


def test_what_a_crash_leaves_is_tidied_at_the_next_start(tmp_path: Path) -> None:
    path = tmp_path / "oxigraph"
    store = OxigraphStore("urn:x:graph", path)
    store.apply([quad(n) for n in range(10)], through=1)
    store.close()
    del store
    # A copy being written, and a finished one the pointer never named (the crash came before the commit).
    (tmp_path / f"oxigraph{REWRITING}").mkdir()
    (tmp_path / f"oxigraph{GENERATION}orphan").mkdir()

    reopened = OxigraphStore("urn:x:graph", path)
    assert reopened.live == path and reopened.applied_through() == 1 and len(texts(reopened)) == 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["oxigraph"]
    reopened.close()
