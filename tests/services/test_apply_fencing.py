"""Fencing the applier: a leader that lost the apply leadership can no longer write.

With the state in PostgreSQL, each acquisition of the apply leadership draws a new epoch, and the store and the
journal's state refuse a write of an older one. Two "hosts" (two write paths on one PostgreSQL database and one
store) show it end to end: the leader's database connection is cut while it applies a batch, the other host
takes over, and every post is applied exactly once, in order, with the store's triples and cursor the journal's.

The embedded store is opened by one process only (RocksDB's lock), so hosts never share one: several hosts share
a remote store (Virtuoso here). On the embedded store the two write paths run in one process and share the store
object, as two hosts share Virtuoso; every writer is then in that process and the store checks the epoch under its
write lock.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path

import psycopg
import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.ops.leadership import SharedLeadership
from segb_server.backend.services.writing.applier import Applied, Applier, quads_of
from segb_server.backend.services.writing.journal import Journal, PostEntry
from segb_server.backend.services.writing.write_path import WritePath
from segb_server.backend.state.epochs import APPLY_LOCK, StateFenced
from segb_server.backend.state.postgres import PostgresDatabase
from segb_server.backend.store.base import Store, StoreFenced
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.store.sparql_http import SparqlHttpStore
from tests.conftest import make_settings, virtuoso_store
from tests.deploy.test_generic_store import oxigraph_server as oxigraph_server  # a fixture
from tests.support.virtuoso import VirtuosoProcess

EX = "https://example.org/"
TRIPLES_PER_POST = 3


def triples(name: str) -> list[Quad]:
    return [Quad(NamedNode(f"{EX}{name}"), NamedNode(f"{EX}p{n}"), Literal(f"{name} {n}")) for n in range(3)]


def post(name: str) -> PostEntry:
    return post_entry(triples(name), "ari", None, "0" * 64)


def stored(store: Store) -> set[tuple[str, str, str]]:
    rows = store.query("SELECT ?s ?p ?o WHERE { ?s ?p ?o }")
    return {(str(row["s"]), str(row["p"]), str(row["o"])) for row in rows}  # type: ignore[union-attr]


def as_rows(quads: list[Quad]) -> set[tuple[str, str, str]]:
    return {(str(quad.subject), str(quad.predicate), str(quad.object)) for quad in quads}


# --- the store refuses an older epoch --------------------------------------------------------------------


def test_a_store_write_of_an_older_epoch_is_refused_and_changes_nothing(store: Store) -> None:
    refuses_older_epochs(store)


@pytest.mark.processes
def test_any_sparql_store_refuses_an_older_epoch(oxigraph_server: str) -> None:
    """The generic adapter's conditional updates, on a second real store (Oxigraph's own server)."""
    store = SparqlHttpStore(
        query_endpoint=f"{oxigraph_server}/query", update_endpoint=f"{oxigraph_server}/update", graph_uri=f"{EX}events"
    )
    try:
        refuses_older_epochs(store)
    finally:
        store.close()


def refuses_older_epochs(store: Store) -> None:
    store.apply(triples("first"), 1, epoch=1)
    store.claim(2)  # a newer leader took over

    with pytest.raises(StoreFenced) as refused:
        store.apply(triples("late"), 2, epoch=1)
    assert (refused.value.epoch, refused.value.newer) == (1, 2)
    with pytest.raises(StoreFenced):
        store.remove(triples("first"), 2, epoch=1)
    with pytest.raises(StoreFenced):
        store.clear(through=2, epoch=1)
    with pytest.raises(StoreFenced):
        store.claim(1)
    assert stored(store) == as_rows(triples("first"))
    assert store.applied_through() == 1

    store.apply(triples("second"), 2, epoch=2)  # the newer leader writes on
    store.remove(triples("first"), 3, epoch=2)
    assert stored(store) == as_rows(triples("second"))
    assert store.applied_through() == 3
    store.apply(triples("third"), 4, epoch=3)  # a newer epoch's first write moves the fence on by itself
    with pytest.raises(StoreFenced):
        store.apply(triples("late"), 5, epoch=2)
    assert store.applied_through() == 4


def test_a_store_written_without_epochs_keeps_doing_so(store: Store) -> None:
    """One host's processes (a file lock, no epoch): the cursor as before, nothing refused."""
    store.apply(triples("first"), 1)
    store.clear(through=2)
    store.apply(triples("second"), 3)
    assert stored(store) == as_rows(triples("second"))
    assert store.applied_through() == 3


def test_the_embedded_store_keeps_its_epoch_across_a_restart(tmp_path: Path) -> None:
    store = OxigraphStore(f"{EX}events", tmp_path / "store")
    store.apply(triples("first"), 1, epoch=3)
    store.close()
    reopened = OxigraphStore(f"{EX}events", tmp_path / "store")
    try:
        with pytest.raises(StoreFenced):
            reopened.apply(triples("late"), 2, epoch=2)
        assert reopened.applied_through() == 1
    finally:
        reopened.close()


@pytest.mark.virtuoso
def test_the_epoch_is_the_stores_own_so_every_client_of_it_sees_it(virtuoso: VirtuosoProcess) -> None:
    """Two hosts each have a client of their own to one Virtuoso graph: the fence is in the store, not the client."""
    old_leader = virtuoso_store(virtuoso)
    new_leader = virtuoso_store(virtuoso, graph_uri=old_leader.graph_uri)
    try:
        old_leader.apply(triples("first"), 1, epoch=4)
        new_leader.claim(5)
        with pytest.raises(StoreFenced):
            old_leader.apply(triples("late"), 2, epoch=4)
        assert stored(new_leader) == as_rows(triples("first"))
        assert new_leader.applied_through() == 1
    finally:
        old_leader.clear()
        old_leader.close()
        new_leader.close()


# --- the journal's state refuses an older epoch ----------------------------------------------------------


@pytest.mark.postgres
def test_each_lead_draws_a_newer_epoch_and_the_journal_state_refuses_an_older_one(postgres_url: str) -> None:
    journal = Journal(PostgresDatabase(postgres_url, writers="journal"))
    first, second = SharedLeadership(postgres_url, APPLY_LOCK), SharedLeadership(postgres_url, APPLY_LOCK)
    try:
        assert first.try_acquire() and first.epoch == 1
        journal.erasure_applied(0, epoch=1)  # the leader's own epoch: accepted
        cut_off(postgres_url, first)
        assert wait_until(second.try_acquire)
        assert second.epoch == 2
        with pytest.raises(StateFenced) as refused:
            journal.erasure_applied(0, epoch=1)
        assert (refused.value.epoch, refused.value.newer) == (1, 2)
        journal.erasure_applied(0, epoch=2)
        second.release()
        time.sleep(SharedLeadership.VERIFY_SECONDS)  # until then the first may not know its connection went
        assert first.try_acquire() and first.epoch == 3  # a lead taken again is a new epoch
    finally:
        first.release()
        second.release()
        journal.close()


@pytest.mark.postgres
def test_a_store_ahead_of_every_epoch_the_state_database_drew_is_claimed_beyond_it(
    store: Store, postgres_url: str, caplog: pytest.LogCaptureFixture
) -> None:
    """The state database restored from an older backup: the store has seen an epoch that database never drew.
    Refusing every leader would stop applying for good; the leader draws an epoch beyond it instead."""
    store.claim(9)
    journal = Journal(PostgresDatabase(postgres_url, writers="journal"))
    leadership = SharedLeadership(postgres_url, APPLY_LOCK)
    writer = Applier(journal, store, batch_triples=100, leadership=leadership)
    try:
        journal.append_posts([post("one")])
        with caplog.at_level(logging.WARNING, logger="segb.applier"):
            assert writer.apply_pending() == 1
        assert leadership.epoch == 10
        assert "which the state database never drew" in caplog.text
        assert stored(store) == as_rows(triples("one"))
        with pytest.raises(StoreFenced):
            store.apply(triples("late"), 2, epoch=9)
    finally:
        leadership.release()
        journal.close()


def cut_off(postgres_url: str, leadership: SharedLeadership) -> None:
    """End the session holding the lock, as a network cut or a restarted connection pooler would."""
    with psycopg.connect(postgres_url, autocommit=True) as admin:
        admin.execute("SELECT pg_terminate_backend(%s)", (leadership._connection.info.backend_pid,))


def wait_until(condition: Callable[[], bool], seconds: float = 10.0) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return False


# --- two hosts, the leader cut off mid-batch --------------------------------------------------------------

POSTS_BEFORE_CLEARING = 12
POSTS_AFTER_CLEARING = 12
STEP_SECONDS = 0.15  # how long the first leader dwells after each step: slow enough to be cut off mid-batch


@pytest.mark.postgres
def test_a_leader_cut_off_mid_batch_is_refused_and_the_other_host_applies_each_post_once_in_order(
    store: Store, request: pytest.FixtureRequest, postgres_url: str, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # The second host's client of the store: its own, to the same Virtuoso graph; on the embedded store, the same.
    remote = store.kind == "virtuoso"
    other_store = virtuoso_store(request.getfixturevalue("virtuoso"), store.graph_uri) if remote else store
    hosts = {
        name: WritePath.open(
            make_settings(
                store=store.kind, state_url=postgres_url, data_dir=tmp_path / name, keep_views=False,
                apply_batch_triples=TRIPLES_PER_POST,  # one post a step
            ),
            client,
            views=[],
        )
        for name, client in (("a", store), ("b", other_store))
    }  # fmt: skip
    journal = hosts["a"].journal
    journal.append_posts([post(f"before/{n}") for n in range(POSTS_BEFORE_CLEARING)])
    journal.append_clear(log_id="clear", user="admin", claimed_user=None)
    journal.append_posts([post(f"after/{n}") for n in range(POSTS_AFTER_CLEARING)])
    head = journal.head()
    store.apply([], 0)  # kept from the journal's start (a new store would start after the clearing)

    written: list[tuple[str, int, int]] = []  # (host, first entry, last entry) of each step the store took, in order
    lock = threading.Lock()

    def recorder(host: str, dwell: float) -> Callable[[Applied], None]:
        def on_applied(step: Applied) -> None:
            with lock:
                written.append((host, step.entries[0].sequence, step.entries[-1].sequence))
            time.sleep(dwell)

        return on_applied

    hosts["a"].on_applied(recorder("a", STEP_SECONDS))
    hosts["b"].on_applied(recorder("b", 0.0))
    try:
        with caplog.at_level(logging.WARNING, logger="segb.applier"):
            hosts["a"].start()
            assert wait_until(lambda: len(written) >= 3), "the first host never applied"
            hosts["b"].start()
            assert not hosts["b"].apply_leadership.held
            leader = hosts["a"].apply_leadership
            assert isinstance(leader, SharedLeadership) and leader.held
            cut_off(postgres_url, leader)
            assert wait_until(lambda: hosts["b"].applier.applied == head, 30), "the second host never caught up"
            assert wait_until(lambda: not hosts["a"].apply_leadership.held, 10), "the cut-off leader never stepped down"
            time.sleep(2 * STEP_SECONDS)  # anything the old leader still wrote would be in by now
    finally:
        for host in hosts.values():
            host.close()
        if other_store is not store:
            other_store.close()

    by_host = {name: [step for step in written if step[0] == name] for name in ("a", "b")}
    assert by_host["a"] and by_host["b"], written
    assert written == by_host["a"] + by_host["b"]  # the old leader wrote nothing once the new one began
    applied = [sequence for _, first, last in written for sequence in range(first, last + 1)]
    assert applied == list(range(1, head + 1))  # every entry once, in order
    assert (hosts["a"].apply_leadership.epoch, hosts["b"].apply_leadership.epoch) == (1, 2)
    assert any("stopped applying the journal" in record.getMessage() for record in caplog.records)

    after_clearing = journal_entries_after_clearing(postgres_url)
    assert stored(store) == as_rows(after_clearing)
    assert store.applied_through() == head


def journal_entries_after_clearing(postgres_url: str) -> list[Quad]:
    journal = Journal(PostgresDatabase(postgres_url, writers="journal"))
    try:
        return quads_of(journal.entries_after(journal.last_clearing(), 1000))
    finally:
        journal.close()
