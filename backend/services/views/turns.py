"""Who may update a view now: the views' work is this process's CPU on the embedded store, which the posts need
too, so how many views update at once is bounded (`Turns`), and who goes next is ranked: the reports first, then
the cheapest batch, then the first come. A small batch (a post) has an express turn of its own."""

from __future__ import annotations

import itertools
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from segb_server.backend.services.reports.folder import FOLDER as REPORTS_FOLDER

Ticket = tuple[int, float, int, bool]  # (rank, cost, arrival, small): lower goes first


def served_first(view: str) -> bool:
    """Whether a view's lane goes before the others waiting for a general turn: the reports'."""
    return view.startswith(f"{REPORTS_FOLDER}/")


class Turns:
    """Who may update a view now: `general` turns for any batch and `express` turns for small ones only. Of the
    lanes waiting, those served first before the others, then the cheapest batch, then the first come. A turn
    freed is handed to the waiter it goes to, and only that one is woken: with a lane per view, waking them all
    on every turn (a condition's notify_all) had some twenty threads contend for the interpreter at each."""

    def __init__(self, general: int, express: int) -> None:
        self._free = {"general": general, "express": express}
        self._waiting: dict[Ticket, _Waiter] = {}
        self._arrivals = itertools.count()
        self._lock = threading.Lock()

    def ticket(self, cost: float, small: bool, first: bool = False) -> Ticket:
        """A place in the queue, kept by a lane that waits for its turn a while at a time."""
        return (0 if first else 1, cost, next(self._arrivals), small)

    @contextmanager
    def turn(self, cost: float, small: bool, first: bool = False) -> Iterator[None]:
        with self.turn_within(self.ticket(cost, small, first), None) as granted:
            assert granted
            yield

    @contextmanager
    def turn_within(self, me: Ticket, timeout: float | None) -> Iterator[bool]:
        """The turn of ticket `me`, waiting at most `timeout` seconds (None: as long as it takes): True when it was
        granted, False when the wait ended first (the ticket keeps its place for the next wait)."""
        waiter = _Waiter()
        with self._lock:
            self._waiting[me] = waiter
            self._grant()
        waiter.granted.wait(timeout)
        with self._lock:
            kind = waiter.kind  # granted, perhaps just as the wait ended
            if kind is None:
                del self._waiting[me]
        try:
            yield kind is not None
        finally:
            if kind is not None:
                with self._lock:
                    self._free[kind] += 1
                    self._grant()

    def _grant(self) -> None:
        """Hand the free turns to the waiters they go to: in rank order, a small batch the express turn while one
        is free, else the first waiter a general turn."""
        for ticket in sorted(self._waiting):
            if not (self._free["express"] or self._free["general"]):
                return
            kind = "express" if ticket[3] and self._free["express"] else "general" if self._free["general"] else None
            if kind is None:
                continue
            self._free[kind] -= 1
            waiter = self._waiting.pop(ticket)
            waiter.kind = kind
            waiter.granted.set()


class _Waiter:
    def __init__(self) -> None:
        self.kind: str | None = None
        self.granted = threading.Event()
