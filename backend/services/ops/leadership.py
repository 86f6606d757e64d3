"""Which of several API processes on one data directory does the work that must have exactly one doer.

Applying the journal to the store must be done by one process at a time: two appliers reading the store's
cursor at different moments could write posts from before a clearing after it. Keeping the views (the
reports' rows, the graph index) current is likewise one writer's job. With `segb serve --workers N` every
worker accepts posts and serves reads; the one holding the lock on `DATA_DIR/leader.lock` also applies and
keeps the views, and the others follow what it did. The lock is the operating system's (`flock`): it is
released when its holder exits or is killed, and another worker takes over within a second.

With the state in PostgreSQL (STATE_URL), API processes on several hosts share one journal and one store, so
applying needs one doer among them all: `SharedLeadership`, an advisory lock in that database. Each host still
keeps its own views (they live in its DATA_DIR), under its own `Leadership`.

A holder cut off from the database learns it only at its next check (up to `VERIFY_SECONDS` later) while another
process may lead already, so each acquisition of a `SharedLeadership` draws a new epoch (`state/epochs.py`), a
fencing token: the applier writes with it, and the store and the journal's state refuse an older one. `epoch` is
None for the other leaderships: one host's processes share one lock whose holder cannot lose it unknowingly.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path
from typing import Any

from segb_server.backend.state.epochs import draw_beyond, next_epoch
from segb_server.backend.state.file_lock import FileLock

logger = logging.getLogger("segb.leadership")

LOCK_FILE = "leader.lock"
# Held by the views' own process (`segb serve` with VIEWS_PROCESS): the API process then holds LOCK_FILE to apply.
VIEWS_LOCK_FILE = "views.lock"


class Leadership:
    """Held by at most one process per lock file; `None` as the path: this process alone (always held)."""

    epoch: int | None = None  # no fencing token: the holder of an `flock` cannot lose it while it lives

    def __init__(self, path: Path | None, doing: str = "applies the journal and keeps the views current") -> None:
        self.path = path
        self.doing = doing  # what the holder does, as the log says it
        self.where = str(path)
        self._file: FileLock | None = None
        self._lock = threading.Lock()
        self._alone = path is None

    @property
    def held(self) -> bool:
        return self._alone or self._file is not None

    def try_acquire(self) -> bool:
        """Take the lock if it is free (never waits); True when this process holds it."""
        if self.held:
            return True
        assert self.path is not None
        with self._lock:
            if self._file is not None:
                return True
            self.path.parent.mkdir(parents=True, exist_ok=True)
            lock = FileLock(self.path)
            if not lock.try_hold():
                lock.close()
                return False
            lock.write_note(f"{os.getpid()}\n")
            self._file = lock
        logger.info("this process (pid %d) %s", os.getpid(), self.doing)
        return True

    def release(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()  # closing it releases the lock
                self._file = None


class Following:
    """Never held: this process follows what another process does (the views kept by a process of their own, or
    the journal applied by the API process, for the views' process)."""

    held = False
    epoch: int | None = None

    def __init__(self, who: str) -> None:
        self.where = who

    def try_acquire(self) -> bool:
        return False

    def release(self) -> None:
        pass


class SharedLeadership:
    """Held by at most one process among all that share a PostgreSQL database: a session-level advisory lock,
    released by the database as soon as its connection ends (the holder exits, is killed, or is cut off).

    The connection stays open between attempts: a follower asks on every wake of its applier (and, with
    INGEST_ACK=store, on every post), and a new PostgreSQL connection costs a server process.

    Each acquisition draws a new `epoch`, one above every holder's before (the fencing token its writes carry)."""

    VERIFY_SECONDS = 0.5  # how often a holder checks its connection still holds the lock

    def __init__(self, url: str, name: str) -> None:
        from segb_server.backend.state.postgres import lock_key, redacted

        self.url = url
        self.where = f"the {name} lock of {redacted(url)}"
        self._name = name
        self._key = lock_key(f"leader:{name}")
        self.epoch: int | None = None  # drawn each time the lock is taken
        self._connection: Any = None
        self._holding = False
        self._verified = 0.0
        self._unreachable = False  # said once in the log, until it answers again
        self._lock = threading.Lock()

    @property
    def held(self) -> bool:
        return self._holding

    def try_acquire(self) -> bool:
        """Take the lock if it is free (never waits); True when this process holds it. A holder whose
        connection was lost holds nothing any more (another process may have the lock): it tries again."""
        with self._lock:
            if self._holding and self._still_held():
                return True
            try:
                row = self._connected().execute("SELECT pg_try_advisory_lock(%s)", (self._key,)).fetchone()
                if row and row[0]:
                    self.epoch = next_epoch(self._connection, self._name)
            except Exception as error:  # the database is away: nobody can lead through it just now
                self._drop_connection()
                if not self._unreachable:
                    logger.warning("cannot reach %s (%s)", self.where, error)
                self._unreachable = True
                return False
            self._unreachable = False
            if not (row and row[0]):
                return False
            self._holding, self._verified = True, time.monotonic()
        logger.info(
            "this process (pid %d) holds %s (apply epoch %s): it applies the journal",
            os.getpid(),
            self.where,
            self.epoch,
        )
        return True

    def draw_beyond(self, seen: int) -> int | None:
        """The holder, when the store has seen apply epoch `seen` that this database never drew: a new epoch
        above it (see `epochs.draw_beyond`); None when `seen` was drawn here (a newer leader's) or the lock is lost."""
        with self._lock:
            if not self._holding:
                return None
            try:
                drawn = draw_beyond(self._connection, self._name, seen)
            except Exception:  # the connection is gone, and with it the lock
                logger.warning("lost %s with its connection", self.where)
                self._drop_connection()
                return None
            if drawn is not None:
                self.epoch = drawn
            return drawn

    def _connected(self) -> Any:
        from segb_server.backend.state.postgres import connect

        if self._connection is None or self._connection.closed or self._connection.broken:
            self._connection = connect(self.url)
        return self._connection

    def _still_held(self) -> bool:
        if time.monotonic() - self._verified < self.VERIFY_SECONDS:
            return True
        try:
            self._connection.execute("SELECT 1")
            self._verified = time.monotonic()
            return True
        except Exception:
            logger.warning("lost %s with its connection", self.where)
            self._drop_connection()
            return False

    def _drop_connection(self) -> None:
        self._holding = False
        if self._connection is not None:
            self._connection.close()
            self._connection = None

    def release(self) -> None:
        """Let the lock go now. Unlocked before the connection closes: a closed connection's session ends a moment
        later on the server, and another process asking in that moment would find the lock still held."""
        with self._lock:
            if self._holding and self._connection is not None:
                try:
                    self._connection.execute("SELECT pg_advisory_unlock(%s)", (self._key,))
                except Exception:  # the connection is gone already, and with it the lock
                    logger.info("%s was released with its connection", self.where)
            self._drop_connection()


Lead = Leadership | SharedLeadership | Following  # what a process may be told to lead by
