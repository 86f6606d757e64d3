"""A view's database: one writer at a time, and a `writing()` inside another joining its transaction (a report's
rows, facets and position change in one commit)."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from segb_server.backend.services.views.database import ViewDatabase

SCHEMA = ["CREATE TABLE IF NOT EXISTS facts (value INTEGER)"]


def values(database: ViewDatabase) -> list[int]:
    return [row[0] for row in database.reader().execute("SELECT value FROM facts ORDER BY value")]


def test_a_nested_writing_joins_the_outer_transaction_and_is_rolled_back_with_it(tmp_path: Path) -> None:
    database = ViewDatabase(tmp_path / "view.sqlite3", SCHEMA)
    try:
        with database.writing() as outer:
            outer.execute("INSERT INTO facts VALUES (1)")
            with database.writing() as inner:
                assert inner is outer
                inner.execute("INSERT INTO facts VALUES (2)")
            assert values(database) == []  # nothing committed before the outer block ends
        assert values(database) == [1, 2]
        with pytest.raises(RuntimeError), database.writing() as outer:
            outer.execute("INSERT INTO facts VALUES (3)")
            with database.writing() as inner:
                inner.execute("INSERT INTO facts VALUES (4)")
            raise RuntimeError("the outer block fails after the nested one ended")
        assert values(database) == [1, 2]
    finally:
        database.close()


def test_writers_on_several_threads_take_turns_each_with_its_own_transaction(tmp_path: Path) -> None:
    database = ViewDatabase(tmp_path / "view.sqlite3", SCHEMA)
    errors: list[BaseException] = []

    def write(base: int) -> None:
        try:
            for number in range(50):
                with database.writing() as connection:
                    connection.execute("INSERT INTO facts VALUES (?)", (base + number,))
                    with database.writing() as nested:
                        nested.execute("INSERT INTO facts VALUES (?)", (-(base + number),))
        except BaseException as error:  # reported below: a thread's exception would otherwise be lost
            errors.append(error)

    threads = [threading.Thread(target=write, args=(1000 * n,)) for n in range(1, 5)]
    try:
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert errors == []
        written = values(database)
        assert len(written) == 400
        assert sorted(v for v in written if v > 0) == sorted(-v for v in written if v < 0)
    finally:
        database.close()


def open_files(path: Path) -> int:
    """This process's file descriptors on the database's file."""
    fds = Path("/proc/self/fd")
    return sum(1 for fd in fds.iterdir() if _target(fd) == str(path))


def _target(fd: Path) -> str:
    try:
        return str(fd.readlink())
    except OSError:  # closed meanwhile
        return ""


def test_the_connections_of_reader_threads_that_ended_are_closed(tmp_path: Path) -> None:
    """The server's worker threads end when idle and new ones start under the next load: each reads on its own
    connection, which must not outlive it (or a busy server runs out of file descriptors)."""
    path = tmp_path / "view.sqlite3"
    database = ViewDatabase(path, SCHEMA)
    try:
        with database.writing() as connection:
            connection.execute("INSERT INTO facts VALUES (1)")
        for _ in range(30):  # one burst of load after another, each on threads of its own
            readers = [threading.Thread(target=values, args=(database,)) for _ in range(4)]
            for reader in readers:
                reader.start()
            for reader in readers:
                reader.join()
        assert values(database) == [1]  # a live reader still reads
        # Bounded by the threads reading at once, not by the bursts (120 connections before the fix): SQLite
        # holds a closed connection's descriptor for reuse while others lock the file, hence a small margin.
        assert open_files(path) <= 16
    finally:
        database.close()
    assert open_files(path) == 0
