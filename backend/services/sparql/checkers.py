"""Checking users' queries (guard.guard_query) outside the server process, each stopped at its query's deadline.

rdflib parses long expressions slowly (a 100 KB query takes it tens of seconds), and only one thread of a
process may parse at a time (parser.py): parsed in the server, one such query would hold every other user's
query behind it, and nothing could stop it. So users' queries are checked in a process of their own
(check_process.py), whose workers each have a parser of their own and are killed at their query's deadline;
a check counts against the query's time limit.

The checking process is shared by every app of the server process, as the parser is; the server's own queries
(the catalog's) keep the parser of the server process.
"""

from __future__ import annotations

import itertools
import logging
import multiprocessing
import threading
import time
from collections import OrderedDict
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess

from segb_server.backend.services.errors import InvalidQuery
from segb_server.backend.services.sparql.check_process import Failure, Outcome, Refusal, serve
from segb_server.backend.services.sparql.guard import CheckedQuery, QueryTooComplex, refuse_unparsable
from segb_server.backend.services.sparql.limits import QueryLimits
from segb_server.backend.store.base import QueryTimeout

logger = logging.getLogger("segb.sparql")

_SPAWN = multiprocessing.get_context("spawn")
MOST_AT_ONCE = 16  # checks running at once; more wait for one to end, and the wait counts against their time
REPLY_GRACE_SECONDS = 2.0  # how much longer than the deadline to wait for the checking process to answer
REMEMBERED = 128  # outcomes kept by text: clients repeat the same queries (report pages)


class _Pending:
    """A check sent to the checking process, until its outcome comes back."""

    def __init__(self, number: int, connection: Connection) -> None:
        self.number = number
        self.connection = connection  # to the checking process that has the check
        self.done = threading.Event()
        self.outcome: Outcome | Failure = "died"

    def settle(self, outcome: Outcome | Failure) -> None:
        self.outcome = outcome
        self.done.set()


class Checkers:
    """The server's side of the checking process: started at the first check, started again if it died."""

    def __init__(self, most: int = MOST_AT_ONCE) -> None:
        self._slots = threading.BoundedSemaphore(most)
        self._lock = threading.Lock()
        self._sending = threading.Lock()  # one message at a time on the pipe
        self._process: BaseProcess | None = None
        self._connection: Connection | None = None
        self._pending: dict[int, _Pending] = {}
        self._numbers = itertools.count()
        self._outcomes: OrderedDict[tuple[str, str | None], Outcome] = OrderedDict()

    def check(self, query: str, events_graph: str | None, limits: QueryLimits) -> CheckedQuery:
        """What guard_query answers, checked before `limits.deadline` (else QueryTimeout)."""
        refuse_unparsable(query)  # cheap, and what makes a check slow: refused here before any parsing
        key = (query, events_graph)
        with self._lock:
            outcome = self._outcomes.get(key)
            if outcome is not None:
                self._outcomes.move_to_end(key)
        if outcome is None:
            outcome = self._check_elsewhere(query, events_graph, limits)
            with self._lock:
                self._outcomes[key] = outcome
                if len(self._outcomes) > REMEMBERED:
                    self._outcomes.popitem(last=False)
        if isinstance(outcome, Refusal):
            raise InvalidQuery(outcome.message, **outcome.details)
        return outcome

    def close(self) -> None:
        with self._lock:
            process, connection = self._process, self._connection
            self._process = self._connection = None
        if connection is not None:
            connection.close()  # the checking process ends its children and itself
        if process is not None:
            process.join(timeout=10)

    def _check_elsewhere(self, query: str, events_graph: str | None, limits: QueryLimits) -> Outcome:
        if not self._slots.acquire(timeout=limits.seconds_left()):
            raise QueryTimeout(limits.timeout_seconds)
        try:
            pending = self._send(query, events_graph, limits)
            if not pending.done.wait(max(0.0, limits.deadline - time.monotonic()) + REPLY_GRACE_SECONDS):
                with self._lock:
                    self._pending.pop(pending.number, None)
                pending.outcome = "timeout"
        finally:
            self._slots.release()
        if pending.outcome == "timeout":
            logger.warning("checking a query took longer than %.1f s and was stopped", limits.timeout_seconds)
            raise QueryTimeout(limits.timeout_seconds)
        if pending.outcome == "died":
            raise QueryTooComplex(
                "The query could not be checked: parsing it took more memory than there was. Simplify it.",
                reason="too_complex",
                line=None,
                column=None,
                query_kind="unknown",
            )
        return pending.outcome

    def _send(self, query: str, events_graph: str | None, limits: QueryLimits) -> _Pending:
        """Hand the query to the checking process; started again if it has died since the last check."""
        seconds = limits.seconds_left()
        try:
            return self._send_once(query, events_graph, seconds)
        except OSError:
            return self._send_once(query, events_graph, seconds)

    def _send_once(self, query: str, events_graph: str | None, seconds: float) -> _Pending:
        with self._lock:
            number = next(self._numbers)
            pending = self._pending[number] = _Pending(number, self._connected())
        try:
            # Not under the lock: the reader takes it to hand outcomes over, and the checking process reads a
            # long query only as its own answers are read.
            with self._sending:
                pending.connection.send((number, query, events_graph, seconds))
        except OSError:
            with self._lock:
                del self._pending[number]
                if self._connection is pending.connection:
                    self._connection = None
            raise
        return pending

    def _connected(self) -> Connection:
        """The connection to the checking process, started if it is not running (called under the lock)."""
        if self._connection is None or self._process is None or not self._process.is_alive():
            theirs, ours = _SPAWN.Pipe()
            process = _SPAWN.Process(target=serve, args=(theirs,), daemon=True, name="segb-query-check")
            process.start()
            theirs.close()
            self._process, self._connection = process, ours
            threading.Thread(target=self._read, args=(ours,), daemon=True, name="segb-query-check").start()
        return self._connection

    def _read(self, connection: Connection) -> None:
        """Hand each outcome to the check waiting for it; when the checking process ends, fail those left."""
        while True:
            try:
                number, outcome = connection.recv()
            except (EOFError, OSError):
                break
            with self._lock:
                pending = self._pending.pop(number, None)
            if pending is not None:
                pending.settle(outcome)
        with self._lock:
            if self._connection is connection:
                self._connection = None
            left = [number for number, pending in self._pending.items() if pending.connection is connection]
            lost = [self._pending.pop(number) for number in left]
        for pending in lost:
            pending.settle("died")


CHECKERS = Checkers()


def guard_user_query(query: str, events_graph: str | None, limits: QueryLimits) -> CheckedQuery:
    """guard_query for a user's query, in the checking process, within the query's time limit: raise
    QueryTimeout when the check is not done by `limits.deadline`."""
    return CHECKERS.check(query, events_graph, limits)
