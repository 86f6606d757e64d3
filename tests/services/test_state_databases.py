"""The journal and the shared contexts on each state database, driven from several connections at once (as
several API processes, or hosts, drive them): SQLite in a data directory, and a real PostgreSQL."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import psycopg
import pytest

from segb_server.backend.services.ops.leadership import SharedLeadership
from segb_server.backend.services.shared_context.policy import Policy
from segb_server.backend.services.shared_context.service import Observation, SharedContextService
from segb_server.backend.services.writing.journal import Journal, PostEntry, triple_digest
from segb_server.backend.state.database import Database
from segb_server.backend.state.postgres import PostgresDatabase
from segb_server.backend.state.sqlite import SqliteDatabase
from tests.conftest import make_settings

PROCESSES = 3
THREADS_PER_PROCESS = 4
POSTS_PER_THREAD = 25

OpenDatabase = Callable[[str], Database]


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def open_database(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[OpenDatabase]:
    """Opens a new connection to one state database each call, as another process would."""
    opened: list[Database] = []
    url = request.getfixturevalue("postgres_url") if request.param == "postgresql" else ""

    def open_connection(writers: str) -> Database:
        if url:
            opened.append(PostgresDatabase(url, writers=writers))
        else:
            opened.append(SqliteDatabase(tmp_path / f"{writers}.sqlite3"))
        return opened[-1]

    yield open_connection
    for database in opened:
        database.close()


def post(robot: int, number: int) -> PostEntry:
    """Three triples: one of the post's own, one the robot re-sends every time, one every robot sends."""
    lines = [
        f'<https://example.org/robot/{robot}/message/{number}> <http://schema.org/text> "hola {number}"@es-ES',
        f"<https://example.org/robot/{robot}> <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> <https://example.org/Robot>",
        '<https://example.org/site> <http://schema.org/name> "lab"^^<http://www.w3.org/2001/XMLSchema#string>',
    ]
    return PostEntry(f"{robot}-{number}", f"robot{robot}", None, f"sha-{robot}-{number}", lines,
                     [triple_digest(line) for line in lines])  # fmt: skip


def test_processes_starting_together_create_the_tables_once(open_database: OpenDatabase) -> None:
    """API workers start at the same moment, each creating the tables it needs if they are not there."""
    connections = [(open_database("journal"), open_database("contexts")) for _ in range(8)]
    start = threading.Barrier(len(connections), timeout=60)  # a thread that failed must not hold the others

    def open_state(databases: tuple[Database, Database]) -> None:
        start.wait()
        Journal(databases[0])
        SharedContextService.open(Policy.from_settings(make_settings()), databases[1])

    with ThreadPoolExecutor(len(connections)) as pool:
        list(pool.map(open_state, connections))  # raises what any of them raised
    [receipt] = Journal(open_database("journal")).append_posts([post(1, 1)])
    assert not isinstance(receipt, BaseException) and receipt.sequence == 1


def test_appenders_in_several_processes_extend_one_chain_and_keep_each_triple_once(
    open_database: OpenDatabase,
) -> None:
    journals = [Journal(open_database("journal")) for _ in range(PROCESSES)]
    robots = [(journal, robot) for robot, journal in enumerate(journals * THREADS_PER_PROCESS)]

    def append(journal_and_robot: tuple[Journal, int]) -> None:
        journal, robot = journal_and_robot
        for number in range(POSTS_PER_THREAD):
            [receipt] = journal.append_posts([post(robot, number)])
            assert not isinstance(receipt, BaseException), receipt

    with ThreadPoolExecutor(len(robots)) as pool:
        list(pool.map(append, robots))

    reader = journals[0]
    total = len(robots) * POSTS_PER_THREAD
    assert reader.head() == total
    verification = reader.verify(deep=True)
    assert (verification.receipts, verification.valid, verification.deep) == (total, True, True)
    entries = reader.entries_after(0, total + 1)
    assert [entry.sequence for entry in entries] == list(range(1, total + 1))
    lines = [line for entry in entries for line in entry.content.decode().splitlines()]
    expected = {
        f"{line} ." for robot in range(len(robots)) for n in range(POSTS_PER_THREAD) for line in post(robot, n).lines
    }
    assert sorted(lines) == sorted(expected)  # every triple once, exactly as received (tags, datatypes kept)


def test_a_clearing_by_one_process_is_seen_by_the_others(open_database: OpenDatabase) -> None:
    first, second = Journal(open_database("journal")), Journal(open_database("journal"))
    [before] = first.append_posts([post(1, 1)])
    [again] = first.append_posts([post(1, 1)])
    assert not isinstance(before, BaseException) and not isinstance(again, BaseException)
    assert (before.triples_new, again.triples_new) == (3, 0)
    cleared = second.append_clear(log_id="clear", user="admin", claimed_user=None)
    assert cleared.triples_removed == 3
    [after] = first.append_posts([post(1, 1)])  # its cache of known triples must not outlive the clearing
    assert not isinstance(after, BaseException)
    assert after.triples_new == 3
    assert second.verify(deep=True).first_broken is None


def test_simultaneous_resolutions_from_several_processes_give_one_context(open_database: OpenDatabase) -> None:
    policy = Policy.from_settings(make_settings())
    services = [SharedContextService.open(policy, open_database("contexts")) for _ in range(PROCESSES)]
    observation = Observation("human_utterance", 1_777_000_000.0, "https://example.org/people/maria", "speech",
                              "good morning robot", "good morning robot")  # fmt: skip
    start = threading.Barrier(16)

    def resolve(call: int) -> str:
        start.wait()
        return services[call % PROCESSES].resolve(observation).shared_context_uri

    with ThreadPoolExecutor(16) as pool:
        uris = set(pool.map(resolve, range(16)))
    assert len(uris) == 1
    for service in services:
        assert service.state.count_by_status() == {"active": 1}


@pytest.mark.postgres
def test_one_process_leads_among_all_sharing_the_database_and_the_lead_moves_when_it_goes(postgres_url: str) -> None:
    first, second = SharedLeadership(postgres_url, "applier"), SharedLeadership(postgres_url, "applier")
    other_role = SharedLeadership(postgres_url, "other")
    try:
        assert first.try_acquire() and first.held
        assert not second.try_acquire() and not second.held
        assert other_role.try_acquire()  # locks of other names are not this one
        first.release()
        assert second.try_acquire()
        assert not first.try_acquire()

        # The holder's connection is cut (as when its host dies): the database frees the lock at once, and the
        # old holder, on its next check, knows it no longer leads.
        with psycopg.connect(postgres_url, autocommit=True) as admin:
            admin.execute("SELECT pg_terminate_backend(%s)", (second._connection.info.backend_pid,))
        deadline_checks = 0
        while not first.try_acquire():
            deadline_checks += 1
            assert deadline_checks < 50, "the lock was never freed"
            threading.Event().wait(0.1)
        threading.Event().wait(SharedLeadership.VERIFY_SECONDS)
        assert not second.try_acquire() and not second.held
    finally:
        for leadership in (first, second, other_role):
            leadership.release()
