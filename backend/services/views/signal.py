"""Waking a process's live-stream readers as soon as a view changes.

The views are written in the projector's threads and the streams read in the event loop: `notify` hands each
waiting reader's loop a wake-up. Readers still poll at their own interval, which covers what a wake-up cannot:
a change made in another process (a follower reads what the leader writes), or one made between a reader's
last look and its wait.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading

import anyio


class ChangeSignal:
    def __init__(self) -> None:
        self._waiting: set[tuple[asyncio.AbstractEventLoop, asyncio.Event]] = set()
        self._lock = threading.Lock()

    def notify(self) -> None:
        """Wake every reader waiting now (from any thread)."""
        with self._lock:
            waiting = list(self._waiting)
        for loop, event in waiting:
            with contextlib.suppress(RuntimeError):  # its loop closed since: nobody left to wake
                loop.call_soon_threadsafe(event.set)

    async def wait(self, timeout: float) -> None:
        """Return at the next `notify`, or after `timeout` seconds."""
        woken = (asyncio.get_running_loop(), asyncio.Event())
        with self._lock:
            self._waiting.add(woken)
        try:
            with anyio.move_on_after(timeout):
                await woken[1].wait()
        finally:
            with self._lock:
                self._waiting.discard(woken)
