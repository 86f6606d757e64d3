"""The process that checks users' queries (guard.guard_query) for the server: see checkers.py for why.

It imports rdflib and warms its parser up once, then forks the workers that check queries: forking takes a few
milliseconds, where starting a process and importing rdflib takes half a second. A worker checks one query at a
time with a parser of its own, and serves the next one after it. One still checking at its query's deadline is
killed; one checking for longer than QUICK_SECONDS is given the lowest CPU priority, so the quick checks beside
it stay quick, and is ended once done (only root may raise a priority again). Forking is safe here: this process
runs one thread.

Spoken to over a pipe: `(number, query, events graph, seconds)` in; `(number, Outcome or Failure)` out, in the
order the checks end.
"""

from __future__ import annotations

import contextlib
import os
import signal
import time
import traceback
from dataclasses import dataclass, field
from multiprocessing import Pipe
from multiprocessing.connection import Connection, wait
from typing import Any, Literal

from segb_server.backend.services.errors import InvalidQuery
from segb_server.backend.services.sparql.guard import CheckedQuery, guard_query

QUICK_SECONDS = 0.5  # a check running longer is given the lowest CPU priority
IDLE_WORKERS = 4  # workers kept waiting for a query; more are ended as their checks end


@dataclass(frozen=True)
class Refusal:
    """Why a query was refused: an InvalidQuery's message and details, as they cross a pipe."""

    message: str
    details: dict[str, Any] = field(default_factory=dict)


Failure = Literal["timeout", "died"]  # stopped at its deadline; or its worker died (out of memory)
Outcome = CheckedQuery | Refusal


@dataclass
class _Worker:
    pid: int
    connection: Connection
    number: int | None = None  # the check it is on; None while it waits for one
    started: float = 0.0
    deadline: float = 0.0
    lowered: bool = False

    def next_event(self) -> float:
        return self.deadline if self.lowered else min(self.deadline, self.started + QUICK_SECONDS)


def serve(connection: Connection) -> None:
    """The checking process's main loop (the target of its process)."""
    workers: list[_Worker] = []

    def stop(*_: object) -> None:
        for worker in workers:
            _kill(worker.pid)
        os._exit(0)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group: the server stops this one
    while True:
        busy = {worker.connection: worker for worker in workers if worker.number is not None}
        now = time.monotonic()
        soonest = min((worker.next_event() for worker in busy.values()), default=now + 60)
        for ready in wait([connection, *busy], timeout=max(0.0, soonest - now)):
            if ready is connection:
                try:
                    number, query, events_graph, seconds = connection.recv()
                except EOFError:  # the server has gone
                    stop()
                worker = _hand(connection, workers, query, events_graph)
                worker.number, worker.started = number, time.monotonic()
                worker.deadline, worker.lowered = worker.started + seconds, False
            else:
                assert isinstance(ready, Connection)
                _reply(connection, busy[ready], workers)
        _watch(connection, workers)


def _hand(connection: Connection, workers: list[_Worker], query: str, events_graph: str | None) -> _Worker:
    """The worker the query was sent to: an idle one, or a new one."""
    idle = next((worker for worker in workers if worker.number is None), None)
    if idle is not None:
        try:
            idle.connection.send((query, events_graph))
            return idle
        except OSError:  # it died while idle (ended by the system)
            _end(idle, workers)
    worker = _fork(connection, workers)
    worker.connection.send((query, events_graph))
    return worker


def _reply(connection: Connection, worker: _Worker, workers: list[_Worker]) -> None:
    try:
        outcome: Outcome | Failure = worker.connection.recv()
    except EOFError:  # it died while checking: the system ended it for want of memory
        outcome = "died"
    connection.send((worker.number, outcome))
    worker.number = None
    idle = sum(1 for other in workers if other.number is None)
    if outcome == "died" or worker.lowered or idle > IDLE_WORKERS:
        _end(worker, workers)


def _watch(connection: Connection, workers: list[_Worker]) -> None:
    """Kill the workers past their deadline, lower the priority of those checking for long."""
    now = time.monotonic()
    for worker in list(workers):
        if worker.number is None:
            continue
        if now > worker.deadline:
            connection.send((worker.number, "timeout"))
            _end(worker, workers)
        elif not worker.lowered and now > worker.started + QUICK_SECONDS:
            worker.lowered = True
            # Suppressed: it has just ended, or the system refuses (then it keeps its priority).
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.setpriority(os.PRIO_PROCESS, worker.pid, 19)


def _fork(connection: Connection, workers: list[_Worker]) -> _Worker:
    ours, theirs = Pipe()
    pid = os.fork()
    if pid == 0:  # the worker; it leaves without running the exit handlers of this process
        try:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)  # this process's handler would kill the other workers
            for other in [connection, ours, *(worker.connection for worker in workers)]:
                other.close()
            _work(theirs)
        except BaseException:
            traceback.print_exc()  # a defect of the checks: the server answers that the query was not checked
            os._exit(1)
        os._exit(0)
    theirs.close()
    worker = _Worker(pid, ours)
    workers.append(worker)
    return worker


def _work(connection: Connection) -> None:
    while True:
        try:
            query, events_graph = connection.recv()
        except EOFError:
            return
        connection.send(_check(query, events_graph))


def _check(query: str, events_graph: str | None) -> Outcome:
    try:
        return guard_query(query, events_graph)
    except InvalidQuery as refused:
        return Refusal(refused.message, refused.details)


def _end(worker: _Worker, workers: list[_Worker]) -> None:
    workers.remove(worker)
    _kill(worker.pid)
    worker.connection.close()


def _kill(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError, ChildProcessError):
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
