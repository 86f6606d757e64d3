"""Watching the store in the background: retry with backoff until it answers, then report losses and returns."""

from __future__ import annotations

import logging

import anyio

from segb_server.backend.store.base import Store, StoreCredentialsRefused, StoreError

logger = logging.getLogger("segb.store")

FIRST_RETRY_SECONDS = 0.5


class StoreMonitor:
    """Pings `store` off the event loop: every failure is logged with the next delay (0.5 s doubling up to
    `max_retry_seconds`); once it answers, one check per `check_seconds`, logging only the transitions.

    A server that starts before its store (a container that comes up before Virtuoso) thereby keeps
    retrying and says so, instead of failing its first requests silently or exiting. A store that refuses the
    server's credentials is an error to correct, logged as one with the store's explanation; the retries go on,
    so a password corrected in the store is picked up."""

    def __init__(self, store: Store, *, max_retry_seconds: float, check_seconds: float) -> None:
        self.store = store
        self.max_retry_seconds = max_retry_seconds
        self.check_seconds = check_seconds
        self.reachable: bool | None = None  # None until the first ping has answered or failed
        # A thread of its own, so a ping never waits behind threads busy with large ingests.
        self._limiter = anyio.CapacityLimiter(1)

    async def run(self) -> None:
        """Run until cancelled."""
        delay = FIRST_RETRY_SECONDS
        attempt = 0
        ever_reachable = False
        while True:
            problem = await self._ping()
            if problem is None:
                if not ever_reachable:
                    logger.info("store reachable (%s)", self.store.kind)
                elif self.reachable is False:
                    logger.info("store back (%s)", self.store.kind)
                ever_reachable, self.reachable = True, True
                delay, attempt = FIRST_RETRY_SECONDS, 0
                await anyio.sleep(self.check_seconds)
                continue
            if self.reachable:
                logger.warning("store lost (%s): %s", self.store.kind, problem)
            self.reachable = False
            attempt += 1
            logger.log(
                logging.ERROR if isinstance(problem, StoreCredentialsRefused) else logging.WARNING,
                "store not reachable (%s, attempt %d): %s; retrying in %.1f s",
                self.store.kind,
                attempt,
                problem,
                delay,
            )
            await anyio.sleep(delay)
            delay = min(delay * 2, self.max_retry_seconds)

    async def _ping(self) -> StoreError | None:
        """None when the store answers, else what went wrong."""
        try:
            await anyio.to_thread.run_sync(self.store.ping, limiter=self._limiter)
        except StoreError as error:
            return error
        return None
