"""One SQLite database a view keeps its rows in: one writer (the projector's thread), many readers.

WAL lets requests read while the writer writes, each reader thread on its own connection. A server without a
data directory (STORE=memory) gets a file in a temporary directory, removed at close: shared-cache memory
databases lock whole tables against readers while a write is under way, which a long build would turn into
failed requests.
"""

from __future__ import annotations

import shutil
import sqlite3
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType

from segb_server.backend.state.sqlite import keep_wal_small, use_wal


class ViewDatabase:
    def __init__(self, path: Path | None, schema: list[str]) -> None:
        self._temporary = Path(tempfile.mkdtemp(prefix="segb-view-")) if path is None else None
        self.path = path if path is not None else self._temporary / "view.sqlite3"  # type: ignore[operator]
        self._local = threading.local()
        self._writer_lock = threading.Lock()
        self._writer: sqlite3.Connection | None = None
        self._writing_thread: int | None = None  # the thread inside `writing()`, whose nested blocks join it
        self._readers: dict[threading.Thread, sqlite3.Connection] = {}
        self._readers_lock = threading.Lock()
        self._rollback_listeners: list[Callable[[], None]] = []
        setup = self._connect()
        try:
            use_wal(setup)
            for statement in schema:
                setup.execute(statement)
        finally:
            setup.close()

    def _connect(self) -> sqlite3.Connection:
        connection = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30)
        connection.execute("PRAGMA busy_timeout=30000")
        connection.execute("PRAGMA synchronous=NORMAL")  # a view is rebuilt from the store if ever lost
        keep_wal_small(connection)  # a view's build writes its whole file in one transaction
        return connection

    def reader(self) -> sqlite3.Connection:
        """This thread's connection for reading."""
        connection = getattr(self._local, "connection", None)
        if connection is None:
            connection = self._local.connection = self._connect()
            with self._readers_lock:
                # The server's worker threads end when idle and others start under the next load: the
                # connections of those that ended are closed here, or each burst would leave its own open.
                for ended in [thread for thread in self._readers if not thread.is_alive()]:
                    self._readers.pop(ended).close()
                self._readers[threading.current_thread()] = connection
        return connection

    @contextmanager
    def snapshot(self) -> Iterator[sqlite3.Connection]:
        """This thread's reader inside one read transaction: what several statements read is one version of the
        database, whatever the writer commits meanwhile. Inside another snapshot, joins it."""
        connection = self.reader()
        if connection.in_transaction:
            yield connection
            return
        connection.execute("BEGIN")
        try:
            yield connection
        finally:
            connection.execute("COMMIT")  # a read transaction: nothing to roll back

    def writer(self) -> sqlite3.Connection:
        """The writer's connection (made on first use): what `writing()` runs on, e.g. to watch the work a step
        does with `set_progress_handler`."""
        if self._writer is None:
            self._writer = self._connect()
        return self._writer

    def writing(self) -> _Writing:
        """`with database.writing() as connection:` one write transaction, one writer at a time. A `writing()`
        inside another, on the same thread, joins the outer transaction (several changes, one commit)."""
        return _Writing(self)

    def on_rollback(self, listener: Callable[[], None]) -> None:
        """Call `listener` (on the writer's thread, before the next writer starts) whenever a write transaction
        is rolled back: what a writer remembers having written in it (the ids it made, a table's dictionary)
        went with it, and kept, would name rows the tables do not hold or numbers the next writer hands out again."""
        self._rollback_listeners.append(listener)

    def close(self) -> None:
        with self._readers_lock:
            for connection in self._readers.values():
                connection.close()
            self._readers.clear()
        if self._writer is not None:
            self._writer.close()
        if self._temporary is not None:
            shutil.rmtree(self._temporary, ignore_errors=True)


class _Writing:
    def __init__(self, database: ViewDatabase) -> None:
        self._database = database
        self._outermost = False

    def __enter__(self) -> sqlite3.Connection:
        database = self._database
        if database._writing_thread == threading.get_ident():
            assert database._writer is not None
            return database._writer
        database._writer_lock.acquire()
        database._writing_thread = threading.get_ident()
        self._outermost = True
        connection = database.writer()
        connection.execute("BEGIN IMMEDIATE")
        return connection

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        if not self._outermost:
            return  # an error leaves through the outer block too, which rolls the whole transaction back
        database = self._database
        connection = database._writer
        rolled_back = kind is not None
        try:
            if connection is not None:
                connection.execute("ROLLBACK" if rolled_back else "COMMIT")
        except BaseException:
            rolled_back = True  # a commit that failed (a full disk): the transaction goes
            if connection is not None and connection.in_transaction:
                connection.execute("ROLLBACK")
            raise
        finally:
            try:
                if rolled_back:
                    for listener in database._rollback_listeners:
                        listener()
            finally:
                database._writing_thread = None
                database._writer_lock.release()
