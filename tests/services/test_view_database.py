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
