"""Where users' SPARQL runs: on a remote store, in the server (the store enforces the time limit and the HTTP
wait is bounded); on the embedded store, in worker processes over a snapshot, stopped at the deadline by
ending the process and bounded in memory — pyoxigraph cannot interrupt a query running in a thread, and an
aggregate over a cross join would otherwise keep a core and gigabytes busy after its client left.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import shutil
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Protocol

from pyoxigraph import QueryResultsFormat, RdfFormat, parse, parse_query_results

from segb_server.backend.services.ops.result_cache import DataVersion
from segb_server.backend.services.sparql.limits import LimitedResult, QueryLimits, run_limited
from segb_server.backend.services.sparql.query_worker import Answer, Ask, serve
from segb_server.backend.store.base import QueryTimeout, Store, StoreError, StoreRejectedQuery
from segb_server.backend.store.oxigraph import OxigraphStore

logger = logging.getLogger("segb.sparql")

# Waiting for a free worker counts against the query's own time limit.
_SPAWN = multiprocessing.get_context("spawn")
WATCH_SECONDS = 0.05  # how often a running query's time and memory are checked
PAGE_BYTES = os.sysconf("SC_PAGE_SIZE")


class QueryTooBig(StoreError):
    """A user query needed more memory than SPARQL_MAX_MEMORY_BYTES allows; its worker was stopped."""

    def __init__(self, limit: int) -> None:
        super().__init__(
            f"The query needed more than {limit // (1 << 20)} MiB (SPARQL_MAX_MEMORY_BYTES) and was stopped; "
            "narrow it down or add a LIMIT."
        )
        self.limit = limit


class QueryRunner(Protocol):
    def run(self, text: str, limits: QueryLimits) -> LimitedResult:
        """The query's answer, at most `limits.max_rows` rows, or QueryTimeout past `limits.deadline`."""

    def close(self) -> None:
        """Stop what the runner started."""

    def forget(self) -> None:
        """Drop every copy of the data made for users' queries (after an erasure): the next query takes a new
        one."""


class InStoreRunner:
    """Runs the query through the store adapter, in the calling thread (for remote stores)."""

    def __init__(self, store: Store) -> None:
        self.store = store

    def run(self, text: str, limits: QueryLimits) -> LimitedResult:
        return run_limited(self.store, text, limits)

    def close(self) -> None:
        pass

    def forget(self) -> None:
        pass  # queries run on the store itself


@dataclass
class _Snapshot:
    key: str
    version: int
    path: Path | None  # a checkpoint directory; None for an in-memory store
    nquads: bytes | None
    users: int = 0


@dataclass
class _Worker:
    process: BaseProcess
    connection: Connection
    snapshot: str | None = None  # the snapshot it holds open


class IsolatedRunner:
    """Worker processes (up to `workers` at once) over snapshots of the embedded store. A snapshot is taken when
    the data changed since the last one (a RocksDB checkpoint: hard links, tens of milliseconds), so a query
    sees every write acknowledged before it; a snapshot no query uses any more is deleted."""

    def __init__(
        self, store: OxigraphStore, version: DataVersion, *, workers: int, max_memory_bytes: int, snapshots: Path | None
    ) -> None:
        self.store = store
        self.version = version
        self.max_memory_bytes = max_memory_bytes
        self.snapshots = snapshots
        self._idle: list[_Worker] = []
        self._slots = threading.BoundedSemaphore(workers)
        self._lock = threading.Lock()
        self._current: _Snapshot | None = None
        self._retired: list[_Snapshot] = []
        if snapshots is not None:
            shutil.rmtree(snapshots, ignore_errors=True)  # left over from a server that was killed
            snapshots.mkdir(parents=True)

    def run(self, text: str, limits: QueryLimits) -> LimitedResult:
        if not self._slots.acquire(timeout=limits.seconds_left()):
            raise QueryTimeout(limits.timeout_seconds)
        try:
            with self._snapshot() as snapshot:
                worker = self._worker()
                answer = self._ask(worker, snapshot, text, limits)
            return _result(answer)
        finally:
            self._slots.release()

    def close(self) -> None:
        with self._lock:
            for worker in self._idle:
                _end(worker)
            self._idle = []
            for snapshot in [*self._retired, *([self._current] if self._current else [])]:
                _delete(snapshot)

    def forget(self) -> None:
        """Retire the current snapshot and delete every one no query is reading; the workers holding one open
        are ended (the files stay readable to a process that has them open, never under DATA_DIR)."""
        with self._lock:
            if self._current is not None:
                self._retired.append(self._current)
                self._current = None
            for worker in self._idle:
                _end(worker)
            self._idle = []
            self._prune()

    def _ask(self, worker: _Worker, snapshot: _Snapshot, text: str, limits: QueryLimits) -> Answer:
        first_time = worker.snapshot != snapshot.key
        ask = Ask(snapshot.key, _path(snapshot), snapshot.nquads if first_time else None, text, limits.max_rows)
        deadline = limits.deadline
        try:
            worker.connection.send(ask)
            # Watch the worker while it runs: ending the process is the only way to stop the query, and its CPU
            # and memory go with it.
            while not worker.connection.poll(WATCH_SECONDS):
                if time.monotonic() > deadline:
                    _end(worker)
                    logger.warning("a query ran past %.1f s and its worker was stopped", limits.timeout_seconds)
                    raise QueryTimeout(limits.timeout_seconds)
                if _resident_bytes(worker.process) > self.max_memory_bytes:
                    _end(worker)
                    logger.warning("a query went past %d bytes and its worker was stopped", self.max_memory_bytes)
                    raise QueryTooBig(self.max_memory_bytes)
            answer: Answer = worker.connection.recv()
        except (EOFError, OSError):  # the worker died (killed by the system for want of memory)
            _end(worker)
            raise QueryTooBig(self.max_memory_bytes) from None
        worker.snapshot = snapshot.key
        with self._lock:
            self._idle.append(worker)
        if answer.kind == "error":
            message = answer.payload.decode("utf-8", "replace")
            if message == "memory":
                raise QueryTooBig(self.max_memory_bytes)
            raise StoreRejectedQuery(message)
        return answer

    def _worker(self) -> _Worker:
        with self._lock:
            if self._idle:
                return self._idle.pop()
        theirs, ours = _SPAWN.Pipe()
        process = _SPAWN.Process(target=serve, args=(theirs,), daemon=True, name="segb-query")
        process.start()
        theirs.close()
        return _Worker(process, ours)

    @contextmanager
    def _snapshot(self) -> Iterator[_Snapshot]:
        with self._lock:
            snapshot = self._fresh_snapshot()
            snapshot.users += 1
        try:
            yield snapshot
        finally:
            with self._lock:
                snapshot.users -= 1
                self._prune()

    def _fresh_snapshot(self) -> _Snapshot:
        version = self.version.value
        if self._current is not None and self._current.version == version:
            return self._current
        key = uuid.uuid4().hex
        if self.snapshots is not None:
            path = self.snapshots / key
            self.store.checkpoint(path)
            snapshot = _Snapshot(key, version, path, None)
        else:
            snapshot = _Snapshot(key, version, None, self.store.dump_nquads())
        if self._current is not None:
            self._retired.append(self._current)
        self._current = snapshot
        return snapshot

    def _prune(self) -> None:
        unused = [snapshot for snapshot in self._retired if snapshot.users == 0]
        self._retired = [snapshot for snapshot in self._retired if snapshot.users]
        for snapshot in unused:
            _delete(snapshot)


def query_runner(
    store: Store, version: DataVersion, *, workers: int, max_memory_bytes: int, snapshots: Path | None
) -> QueryRunner:
    if isinstance(store, OxigraphStore):
        return IsolatedRunner(store, version, workers=workers, max_memory_bytes=max_memory_bytes, snapshots=snapshots)
    return InStoreRunner(store)


def _result(answer: Answer) -> LimitedResult:
    if answer.kind == "graph":
        triples = [quad.triple for quad in parse(answer.payload, RdfFormat.N_TRIPLES)]
        return LimitedResult(triples, answer.truncated, answer.rows)
    parsed = parse_query_results(answer.payload, QueryResultsFormat.JSON)
    return LimitedResult(parsed, answer.truncated, answer.rows)


def _path(snapshot: _Snapshot) -> str | None:
    return None if snapshot.path is None else str(snapshot.path)


def _resident_bytes(process: BaseProcess) -> int:
    """The worker's resident memory, read from /proc (0 where there is none to read)."""
    try:
        with open(f"/proc/{process.pid}/statm") as statm:
            return int(statm.read().split()[1]) * PAGE_BYTES
    except (FileNotFoundError, ProcessLookupError, IndexError, ValueError):
        return 0


def _end(worker: _Worker) -> None:
    worker.process.kill()
    worker.process.join(timeout=10)
    worker.connection.close()


def _delete(snapshot: _Snapshot) -> None:
    if snapshot.path is not None:
        shutil.rmtree(snapshot.path, ignore_errors=True)
