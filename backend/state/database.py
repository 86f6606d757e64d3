"""What the journal and the shared-context state need from a relational database, whichever it is.

Callers write SQL once, in the dialect both SQLite and PostgreSQL accept, with `?` placeholders; a schema
spells its few differing types as `{serial}` (a key the database assigns), `{blob}`, `{real}`, `{without_rowid}`.
Writers go through `writing()`, which serialises them across every process sharing the database — threads,
API workers, hosts — so an append extends one chain and never forks it.

A database object is one connection; its methods take its lock, so threads may share it. Blocking: async
callers use a worker thread.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager, nullcontext
from typing import Any, Protocol


class StateUnavailable(Exception):
    """The state database cannot be reached just now (a PostgreSQL server restarting, the network cut); the call
    kept nothing, and the next one tries again."""


class Rows(Protocol):
    @property
    def rowcount(self) -> int: ...

    def fetchone(self) -> Any: ...
    def fetchall(self) -> list[Any]: ...
    def __iter__(self) -> Iterator[Any]: ...


class Database(ABC):
    kind: str
    where: str  # for messages: the file, or the server

    def __init__(self) -> None:
        self._lock = threading.RLock()

    @abstractmethod
    def execute(self, sql: str, params: Sequence[object] = ()) -> Rows:
        """Run one statement (in the current transaction, if any) and return its rows."""

    def script(self, schema: str) -> None:
        """Create what `schema` declares (re-runnable: `CREATE … IF NOT EXISTS`), as one writer: processes
        starting together would otherwise race to create the same table (PostgreSQL then fails one of them)."""
        with self.writing():
            for statement in self.render(schema).split(";"):
                if statement.strip():
                    self.execute(statement)

    @abstractmethod
    def render(self, schema: str) -> str:
        """`schema` with its type placeholders spelt for this database."""

    @abstractmethod
    def columns(self, table: str) -> set[str]:
        """The names of a table's columns (to add those an older version did not have)."""

    @contextmanager
    def writing(self) -> Iterator[None]:
        """A transaction no other writer of this database runs beside, in any process."""
        with self._lock, self._writers_queue():
            self.execute(self.begin_writing)
            try:
                self._after_begin_writing()
                yield
            except BaseException:
                self.rollback()
                raise
            self.execute("COMMIT")

    @contextmanager
    def reading(self) -> Iterator[None]:
        """A transaction that reads one consistent state without holding writers up."""
        with self._lock:
            self.execute(self.begin_reading)
            try:
                yield
            finally:
                self.rollback()

    begin_writing = "BEGIN"
    begin_reading = "BEGIN"

    def _writers_queue(self) -> AbstractContextManager[object]:
        """Held around each write transaction: where writers of other processes wait their turn, when the
        database's own waiting is worse."""
        return nullcontext()

    def _after_begin_writing(self) -> None:
        """Run first in each write transaction (e.g. to take a lock the transaction's end releases)."""
        return None

    @abstractmethod
    def rollback(self) -> None:
        """End the current transaction, if any, keeping nothing of it."""

    @abstractmethod
    def size_bytes(self) -> int:
        """How much space the database takes."""

    @abstractmethod
    def free_bytes(self) -> int | None:
        """Free space where the database grows, or None where this server cannot tell (a remote server)."""

    @abstractmethod
    def out_of_space(self, error: BaseException) -> bool:
        """Whether `error` says the database could not grow."""

    def continue_serials(self, table: str) -> None:
        """After rows were inserted with their keys given, make the keys the database assigns follow them."""
        return None

    def compact(self) -> None:
        """Leave nothing removed in the database's files where this server can see to it (after an erasure)."""
        return None

    def reader(self) -> Database:
        """A database to read this one's committed state through without waiting for its write transactions
        (another connection, where the database lets one read beside a writer); this one where it does not.
        Its caller closes it when it is not this one."""
        return self

    def ping(self) -> None:
        """Raise StateUnavailable unless the database answers."""
        self.execute("SELECT 1").fetchone()

    @abstractmethod
    def close(self) -> None: ...
