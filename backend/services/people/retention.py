"""Retention: posts older than RETENTION_DAYS lose their content, by the same erasure as a person's (one journal
entry each time, receipts and erasure records kept), on a schedule, in the one process that applies the journal.
The server log's older entries and the shared contexts' older observations go too."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from datetime import UTC, datetime, timedelta

from segb_server.backend.services.people.erasure import ErasureResult, ErasureService

logger = logging.getLogger("segb.people")

RETENTION_USER = "segb-retention"  # the ledger's `user` of retention's erasures


def cutoff(days: int, now: datetime) -> str:
    """The time before which posts are past retention, as receipts write times (the calendar's first instant when
    counting back `days` leaves it: nothing was posted before that)."""
    try:
        start = now.astimezone(UTC) - timedelta(days=days)
    except OverflowError:
        start = datetime.min.replace(tzinfo=UTC)
    return start.isoformat(timespec="microseconds").replace("+00:00", "Z")


class Retention:
    def __init__(self, erasure: ErasureService, days: int, every_seconds: float, applies: Callable[[], bool]) -> None:
        """`applies`: whether this process applies the journal (only that one erases on schedule)."""
        self.erasure = erasure
        self.days = days
        self.every_seconds = every_seconds
        self.applies = applies
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def run_once(self, now: datetime | None = None) -> ErasureResult | None:
        """Erase what is past retention at `now` (default: now); None when nothing was."""
        before = cutoff(self.days, now or datetime.now(UTC))
        reason = f"posts recorded before {before} (RETENTION_DAYS={self.days})"
        return self.erasure.erase_before(before, reason, RETENTION_USER)

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="segb-retention", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=30)

    def _run(self) -> None:
        while not self._stop.wait(self.every_seconds):
            if not self.applies():
                continue
            try:
                self.run_once()
            except Exception:  # the next run tries again; meanwhile posts are kept, never lost
                logger.exception("erasing posts past retention failed")
