"""SQLite, the default: a file in DATA_DIR (WAL mode), or memory for a server meant to keep nothing."""

from __future__ import annotations

import shutil
import sqlite3
import time
from collections.abc import Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path

from segb_server.backend.state.database import Database, Rows
from segb_server.backend.state.file_lock import FileLock

TYPES = {"serial": "INTEGER PRIMARY KEY", "blob": "BLOB", "real": "REAL", "without_rowid": "WITHOUT ROWID"}
# What a write-ahead log keeps of its size once its pages are in the file. SQLite otherwise leaves the log at the
# largest size one transaction ever made it, for as long as the server runs: a view built at a million triples
# left 78 MiB beside the graph index's 77. A log that fits one ordinary batch is reused without growing.
WAL_KEPT_BYTES = 4 * 2**20
WAL_SWITCH_SECONDS = 30.0  # how long opening a file waits for another process's write to let it switch to WAL
WAL_SWITCH_PAUSE = 0.01


def use_wal(connection: sqlite3.Connection) -> None:
    """Put the connection's file in WAL mode. SQLite refuses the switch ("database is locked") at once, without
    its busy timeout, while another connection writes to a file still in rollback mode: API workers and the
    views' process opening a fresh data directory together. Tried again until that write is done."""
    deadline = time.monotonic() + WAL_SWITCH_SECONDS
    while True:
        try:
            connection.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as error:
            if error.sqlite_errorcode != sqlite3.SQLITE_BUSY or time.monotonic() > deadline:
                raise
            time.sleep(WAL_SWITCH_PAUSE)


def keep_wal_small(connection: sqlite3.Connection) -> None:
    """Truncate the connection's write-ahead log to WAL_KEPT_BYTES when it restarts after a checkpoint."""
    connection.execute(f"PRAGMA journal_size_limit={WAL_KEPT_BYTES}")


def vacuum(path: Path) -> None:
    """Write a SQLite file anew from what it holds, and empty its write-ahead log: rows deleted before (a view
    built again after an erasure) leave nothing in the file. Another connection may use the file meanwhile."""
    if not path.exists():
        return
    connection = sqlite3.connect(str(path), isolation_level=None, timeout=60)
    try:
        connection.execute("VACUUM")
        connection.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    finally:
        connection.close()


class SqliteDatabase(Database):
    kind = "sqlite"

    def __init__(self, path: Path | None, *, sync_full: bool = False, reads_only: bool = False) -> None:
        super().__init__()
        self.path = path
        self.where = str(path.parent) if path is not None else "memory"
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
        self._connection = sqlite3.connect(
            ":memory:" if path is None else str(path), isolation_level=None, check_same_thread=False, timeout=30
        )
        # Writers of other processes (API workers) queue on this lock, which wakes the next one as soon as it is
        # released; SQLite's own busy wait sleeps in steps of up to 100 ms.
        self._writers = None if path is None or reads_only else FileLock(path.with_name(f"{path.name}.lock"))
        if path is not None and reads_only:
            self._connection.execute("PRAGMA query_only=ON")
        elif path is not None:
            # WAL: a commit is durable across a crash of the server process. NORMAL sync leaves the newest
            # commits to the operating system's cache on a power cut; FULL syncs every commit (slower).
            use_wal(self._connection)
            keep_wal_small(self._connection)
            self._connection.execute(f"PRAGMA synchronous={'FULL' if sync_full else 'NORMAL'}")
            # Freed pages are overwritten: content an erasure removed must not linger in the file.
            self._connection.execute("PRAGMA secure_delete=ON")

    # IMMEDIATE takes SQLite's write lock up front: even a writer of another process cannot interleave.
    begin_writing = "BEGIN IMMEDIATE"

    def execute(self, sql: str, params: Sequence[object] = ()) -> Rows:
        with self._lock:
            return self._connection.execute(sql, params)

    def render(self, schema: str) -> str:
        return schema.format(**TYPES)

    def columns(self, table: str) -> set[str]:
        return {row[1] for row in self.execute(f"PRAGMA table_info({table})")}

    def _writers_queue(self) -> AbstractContextManager[object]:
        return self._writers.held() if self._writers is not None else nullcontext()

    def rollback(self) -> None:
        with self._lock:
            if self._connection.in_transaction:
                self._connection.execute("ROLLBACK")

    def reader(self) -> Database:
        # In WAL mode a second connection reads the last committed state while a write transaction runs (and
        # syncs its commit); a database in memory exists for its one connection only.
        return self if self.path is None else SqliteDatabase(self.path, reads_only=True)

    def size_bytes(self) -> int:
        # Pages, not the file's size: inside a transaction they count what it is about to add.
        pages, page_size = (self.execute(f"PRAGMA {name}").fetchone()[0] for name in ("page_count", "page_size"))
        return int(pages * page_size)

    def free_bytes(self) -> int | None:
        return None if self.path is None else shutil.disk_usage(self.path.parent).free

    def out_of_space(self, error: BaseException) -> bool:
        return isinstance(error, sqlite3.OperationalError) and ("full" in str(error) or "disk I/O" in str(error))

    def compact(self) -> None:
        # Freed pages are zeroed (secure_delete); the write-ahead log still holds the old pages until it is
        # checkpointed and truncated.
        if self.path is not None:
            with self._lock:
                self._connection.execute("PRAGMA wal_checkpoint(TRUNCATE)")

    def close(self) -> None:
        with self._lock:
            self._connection.close()
            if self._writers is not None:
                self._writers.close()
