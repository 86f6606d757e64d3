"""SQLite files opened by several processes at once: API workers and the views' process start together on a
fresh data directory, each opening the journal's and the views' files and switching them to WAL. SQLite answers
a switch attempted while another connection writes to a file still in rollback mode "database is locked" at once,
whatever the busy timeout; a worker that let that through failed its start, and uvicorn stopped every worker."""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.state.sqlite import SqliteDatabase

SCHEMA = ["CREATE TABLE IF NOT EXISTS facts (value INTEGER)"]
HELD_SECONDS = 0.5


def open_view(path: Path) -> Callable[[], None]:
    return ViewDatabase(path, SCHEMA).close


def open_state(path: Path) -> Callable[[], None]:
    return SqliteDatabase(path).close


@pytest.mark.parametrize("open_database", [open_view, open_state], ids=["view", "state"])
def test_a_file_another_process_is_writing_in_rollback_mode_is_opened_once_it_is_done(
    tmp_path: Path, open_database: Callable[[Path], Callable[[], None]]
) -> None:
    path = tmp_path / "fresh.sqlite3"
    other = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
    other.execute("BEGIN IMMEDIATE")  # another process creating its tables, the file not yet in WAL
    other.execute("CREATE TABLE IF NOT EXISTS others (value INTEGER)")
    done = threading.Timer(HELD_SECONDS, lambda: other.execute("COMMIT"))
    done.start()
    try:
        close = open_database(path)  # raised sqlite3.OperationalError "database is locked" at once
        close()
    finally:
        done.join()
        other.close()
    with sqlite3.connect(path) as check:
        assert check.execute("PRAGMA journal_mode").fetchone() == ("wal",)
        assert {row[0] for row in check.execute("SELECT name FROM sqlite_master")} >= {"others"}
