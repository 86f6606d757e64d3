"""Which of several API processes on one data directory does the work that must have exactly one doer.

Applying the journal to the store must be done by one process at a time: two appliers reading the store's
cursor at different moments could write posts from before a clearing after it. Keeping the views (the
reports' rows, the graph index) current is likewise one writer's job. With `segb serve --workers N` every
worker accepts posts and serves reads; the one holding the lock on `DATA_DIR/leader.lock` also applies and
keeps the views, and the others follow what it did. The lock is the operating system's (`flock`): it is
released when its holder exits or is killed, and another worker takes over within a second.
"""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path

from segb_server.backend.services.ops.file_lock import FileLock

logger = logging.getLogger("segb.leadership")

LOCK_FILE = "leader.lock"


class Leadership:
    """Held by at most one process per lock file; `None` as the path: this process alone (always held)."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
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
        logger.info("this process (pid %d) applies the journal and keeps the views current", os.getpid())
        return True

    def release(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()  # closing it releases the lock
                self._file = None
