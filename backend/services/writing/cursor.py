"""How far a background worker (the applier, the views' keeper) is through the journal, which others wait on."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable


class Cursor:
    """A journal sequence that only moves forward, and waiting for it to reach one."""

    def __init__(self) -> None:
        self._value = 0
        self._moved = threading.Condition()

    @property
    def value(self) -> int:
        return self._value

    def advance(self, to: int) -> None:
        """Move to `to` (never backwards) and wake whoever waits."""
        with self._moved:
            if to > self._value:
                self._value = to
            self._moved.notify_all()

    def set(self, to: int) -> None:
        """Move to `to`, backwards too (a store found restored or wiped is applied again from its own cursor)."""
        with self._moved:
            self._value = to
            self._moved.notify_all()

    def wait_for(
        self,
        sequence: int,
        timeout: float,
        *,
        reached: Callable[[], bool] = lambda: True,
        poll: Callable[[], None] | None = None,
        poll_seconds: float = 0.05,
    ) -> bool:
        """Wait until the cursor is at `sequence` or past it and `reached()` holds (True), or `timeout` seconds
        passed (False). `poll`: called every `poll_seconds` while waiting, outside the lock, for a cursor moved
        by another process (a follower reads the leader's progress instead of being woken)."""
        deadline = time.monotonic() + timeout
        with self._moved:
            while self._value < sequence or not reached():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                if poll is None:
                    self._moved.wait(remaining)
                    continue
                self._moved.release()
                try:
                    poll()
                    time.sleep(min(poll_seconds, remaining))
                finally:
                    self._moved.acquire()
        return True
