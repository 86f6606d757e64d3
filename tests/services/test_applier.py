"""The applier on its own (the journal and the embedded store in memory): entries written into the store in order,
in batches, a clearing a step of its own, the store's cursor kept with its triples so a restart resumes there,
and a process that does not lead only following what the leader applied."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.ops.leadership import Leadership
from segb_server.backend.services.writing.applier import Applied, Applier
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.state.sqlite import SqliteDatabase
from segb_server.backend.store.oxigraph import OxigraphStore

EX = "https://example.org/"


def record(journal: Journal, *values: str) -> None:
    """One post per value, each a triple of its own."""
    quads = [[Quad(NamedNode(EX + value), NamedNode(EX + "p"), Literal(value))] for value in values]
    journal.append_posts([post_entry(q, "ari", None, "0" * 64) for q in quads])


def applier(journal: Journal, store: OxigraphStore, batch_triples: int = 1000, **options: object) -> Applier:
    return Applier(journal, store, batch_triples=batch_triples, **options)  # type: ignore[arg-type]


def test_pending_entries_are_written_in_batches_with_the_store_cursor() -> None:
    journal, store = Journal(SqliteDatabase(None)), OxigraphStore("urn:x:events")
    record(journal, "a", "b", "c", "d", "e")
    steps: list[Applied] = []
    writer = applier(journal, store, batch_triples=2)
    writer.on_applied(steps.append)

    assert writer.apply_pending() == 5
    assert [[entry.sequence for entry in step.entries] for step in steps] == [[1, 2], [3, 4], [5]]
    assert [len(step.quads) for step in steps] == [2, 2, 1]
    assert store.count() == 5 and store.applied_through() == 5
    assert writer.applied == 5 and writer.lag() == (0, 0.0)
    assert writer.apply_pending() == 5 and len(steps) == 3  # nothing more to do


def test_a_clearing_is_a_step_of_its_own_and_a_new_store_starts_after_the_last_one() -> None:
    journal, store = Journal(SqliteDatabase(None)), OxigraphStore("urn:x:events")
    record(journal, "a", "b")
    steps: list[Applied] = []
    writer = applier(journal, store)
    writer.on_applied(steps.append)
    writer.apply_pending()
    journal.append_clear(log_id="clear", user="admin", claimed_user=None)
    record(journal, "c", "d")
    writer.apply_pending()
    assert [(step.cleared, [e.sequence for e in step.entries]) for step in steps] == [
        (False, [1, 2]),
        (True, [3]),
        (False, [4, 5]),
    ]
    assert store.count() == 2 and store.applied_through() == 5

    fresh = OxigraphStore("urn:x:events")  # no cursor: what came before the clearing is gone anyway
    assert applier(journal, fresh).apply_pending() == 5 and fresh.count() == 2


def test_a_restart_resumes_at_the_stores_cursor_and_a_store_from_another_journal_is_applied_again() -> None:
    journal, store = Journal(SqliteDatabase(None)), OxigraphStore("urn:x:events")
    record(journal, "a", "b")
    applier(journal, store).apply_pending()
    record(journal, "c")
    steps: list[Applied] = []
    restarted = applier(journal, store)
    restarted.on_applied(steps.append)
    restarted.apply_pending()
    assert [e.sequence for step in steps for e in step.entries] == [3]  # not 1 and 2 again

    other = Journal(SqliteDatabase(None))  # a store applied further than this journal goes: not this journal's
    record(other, "z")
    again = applier(other, store)
    assert again.apply_pending() == 1 and store.applied_through() == 1


def test_a_process_that_does_not_lead_follows_the_store_cursor(tmp_path: Path) -> None:
    journal, store = Journal(SqliteDatabase(None)), OxigraphStore("urn:x:events")
    record(journal, "a", "b")
    leader_lock, follower_lock = Leadership(tmp_path / "leader.lock"), Leadership(tmp_path / "leader.lock")
    leader = applier(journal, store, leadership=leader_lock)
    follower = applier(journal, store, leadership=follower_lock)
    assert leader.apply_pending() == 2
    assert not follower_lock.try_acquire()
    record(journal, "c")
    assert follower.apply_pending() == 2  # read, not applied: the leader has not applied entry 3 yet
    assert store.count() == 2 and follower.lag()[0] == 1
    leader.apply_pending()
    assert follower.wait_for(3, timeout=10)  # it polls the store's cursor while it waits
    leader_lock.release()
    follower_lock.release()


def test_the_background_thread_applies_what_it_is_told_of() -> None:
    journal, store = Journal(SqliteDatabase(None)), OxigraphStore("urn:x:events")
    writer = applier(journal, store)
    writer.start()
    try:
        record(journal, "a")
        writer.notify()
        assert writer.wait_for(1, timeout=10)
        assert store.count() == 1 and writer.last_error is None
    finally:
        writer.stop()
