"""How long a post's answer waits for the views: robots slow down to the pace the views keep.

A post is answered once it is durable (and, with INGEST_ACK=store, applied); the views take it afterwards, in
the process that leads. Within one process the interpreter shares its time between posts and views, so posts
slow down as the views work. With several API workers (`--workers`, the compose default) the others accept
posts at full speed while the leader keeps the views, and under a sustained stream the views fall behind
without end: the reports then show what robots did minutes ago.

So while the views are further behind than VIEWS_MAX_LAG_SECONDS (the oldest entry they miss has waited that
long), a post's answer waits, VIEWS_MAX_HOLD_SECONDS at most. It is never refused — the post is already kept —
and robots, which wait for each answer before their next post, post at the pace the views keep. Nothing waits
while the views are failing (their keeper retrying an error) or while every view is being built from the store
(at start, or again after an erasure: minutes on a big store): waiting would not make them faster, and the posts
they then miss are caught up in batches afterwards.
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Protocol

logger = logging.getLogger("segb.ingest")

POLL_SECONDS = 0.05  # how often a waiting post looks again, and how long one look serves every post


class ViewsProgress(Protocol):
    def views_behind(self) -> int: ...  # entries the store has and the views do not (read in memory)

    def views_lag_seconds(self) -> float: ...  # how long the oldest of them has waited (reads the journal)

    def views_failing(self) -> bool: ...

    def views_building_all(self) -> bool: ...  # every view being built from the store (at start, after an erasure)


class ViewsPace:
    def __init__(self, progress: ViewsProgress, max_lag_seconds: float, max_hold_seconds: float) -> None:
        self._progress = progress
        self.max_lag_seconds = max_lag_seconds
        self.max_hold_seconds = max_hold_seconds
        # The last look at the views' lag, shared by the posts answered meanwhile: (time.monotonic(), too far).
        # Read and written on the event loop only.
        self._last_look = (float("-inf"), False)

    async def hold(self) -> float:
        """Wait while the views are too far behind, up to the longest hold; the seconds waited."""
        if self.max_lag_seconds <= 0 or self.max_hold_seconds <= 0:
            return 0.0
        began = time.monotonic()
        while await self._too_far_behind():
            waited = time.monotonic() - began
            if waited >= self.max_hold_seconds:
                break
            await asyncio.sleep(min(POLL_SECONDS, self.max_hold_seconds - waited))
        return time.monotonic() - began

    async def _too_far_behind(self) -> bool:
        if not self._progress.views_behind():  # in memory: the common case needs no look at the journal
            return False
        looked_at, too_far = self._last_look
        if time.monotonic() - looked_at < POLL_SECONDS:
            return too_far
        too_far = await asyncio.to_thread(self._look)
        self._last_look = (time.monotonic(), too_far)
        return too_far

    def _look(self) -> bool:
        try:
            if self._progress.views_failing() or self._progress.views_building_all():
                return False
            return self._progress.views_lag_seconds() > self.max_lag_seconds
        except Exception as error:  # the post is kept already: a failed look must not fail its answer
            logger.warning("could not read how far the views are behind (%s); the post is answered", error)
            return False
