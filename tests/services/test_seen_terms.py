"""The registry of IRIs the store has held: it tells a batch's fresh IRIs, and never calls fresh an IRI the store
held before the batch (a view would then miss older triples about it)."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import Quad, RdfFormat, parse

from segb_server.backend.services.views.seen_terms import SeenTerms
from segb_server.backend.store.oxigraph import OxigraphStore

EX = "https://example.org/"


def quads(*lines: str) -> list[Quad]:
    return list(parse("\n".join(lines).encode(), RdfFormat.N_TRIPLES))


def triple(subject: str, predicate: str, object_: str) -> str:
    return f"<{EX}{subject}> <{EX}{predicate}> {object_} ."


def built(tmp_path: Path, *lines: str) -> tuple[SeenTerms, OxigraphStore]:
    store = OxigraphStore("http://amor-segb/events", tmp_path / "store")
    store.apply(quads(*lines), 1)
    seen = SeenTerms(tmp_path / "seen.sqlite3")
    seen.build(store, 1)
    return seen, store


def test_the_iris_of_a_batch_the_store_never_held_are_fresh(tmp_path: Path) -> None:
    seen, store = built(tmp_path, triple("robot", "name", '"ARI"'))
    batch = quads(
        triple("activity1", "performedBy", f"<{EX}robot>"),
        triple("activity1", "about", "_:event"),
        triple("activity1", "label", '"a literal is never fresh"'),
    )
    fresh = seen.admit(batch, 2, 2)
    assert fresh == {f"<{EX}activity1>"}  # the robot was held before; a blank node is never fresh
    assert seen.stored_through() == 2
    # The next batch mentions the activity again: the store now holds triples about it.
    assert seen.admit(quads(triple("activity1", "endedAt", f"<{EX}time2>")), 3, 3) == {f"<{EX}time2>"}
    store.close()
    seen.close()


def test_nothing_is_fresh_when_the_registry_misses_earlier_steps(tmp_path: Path) -> None:
    seen, store = built(tmp_path, triple("robot", "name", '"ARI"'))
    # Step 2 went by without the registry: an IRI it mentioned must not look fresh in step 3.
    assert seen.admit(quads(triple("message3", "sender", f"<{EX}visitor>")), 3, 3) == frozenset()
    assert seen.stored_through() == 3
    assert seen.admit(quads(triple("message4", "sender", f"<{EX}visitor>")), 4, 4) == {f"<{EX}message4>"}
    store.close()
    seen.close()


def test_an_unbuilt_registry_tells_nothing_fresh_and_stays_unbuilt(tmp_path: Path) -> None:
    seen = SeenTerms(tmp_path / "seen.sqlite3")
    assert seen.stored_through() is None
    assert seen.admit(quads(triple("a", "p", f"<{EX}b>")), 1, 1) == frozenset()
    assert seen.stored_through() is None
    seen.close()


def test_a_build_registers_every_iri_of_the_store(tmp_path: Path) -> None:
    lines = [triple(f"node{n}", "next", f"<{EX}node{n + 1}>") for n in range(50_000)]
    seen, store = built(tmp_path, *lines)
    again = quads(triple("node0", "p", f"<{EX}node50000>"), triple("node49999", "q", f"<{EX}new>"))
    assert seen.admit(again, 2, 2) == {f"<{EX}new>"}
    store.close()
    seen.close()


def test_after_a_clearing_the_iris_held_before_are_fresh_again(tmp_path: Path) -> None:
    seen, store = built(tmp_path, triple("robot", "name", '"ARI"'))
    seen.clear(2)
    assert seen.admit(quads(triple("robot", "name", '"ARI"')), 3, 3) == {f"<{EX}robot>"}
    store.close()
    seen.close()


def test_the_registry_outlives_the_process(tmp_path: Path) -> None:
    seen, store = built(tmp_path, triple("robot", "name", '"ARI"'))
    seen.admit(quads(triple("visit1", "by", f"<{EX}robot>")), 2, 2)
    seen.close()
    reopened = SeenTerms(tmp_path / "seen.sqlite3")
    assert reopened.stored_through() == 2
    assert reopened.admit(quads(triple("visit1", "at", f"<{EX}visit2>")), 3, 3) == {f"<{EX}visit2>"}
    reopened.close()
    store.close()
