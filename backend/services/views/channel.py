"""The embedded store read by another process of the same server, over a local socket.

RocksDB lets one process open the embedded store. `segb serve` keeps the views in a process of their own
(`backend/services/views/process.py`), so the requests' interpreter never waits for the views' Python; that process
reads the store through the API process that opened it. `StoreChannel` serves the store's reads there: a Unix
socket, each connection authenticated with a random key both processes hold (multiprocessing.connection's HMAC
handshake), one thread per connection. On Linux the socket has an abstract name: no file, so a server killed
with SIGKILL leaves nothing behind; elsewhere it is a file in a private temporary directory (mode 0700), removed
when the channel closes. `ChannelStore` is the `Store` the other process uses, one connection per thread that
reads.

An answer is the store's own, evaluated and written as SPARQL JSON (or N-Triples for a CONSTRUCT) by pyoxigraph
without the interpreter lock: the API's requests do not wait while the views' queries run. Nothing is written
through the channel: the API process alone applies the journal.
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
import shutil
import socket
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Client, Connection, Listener
from pathlib import Path

from pyoxigraph import (
    DefaultGraph,
    Quad,
    QueryBoolean,
    QueryResultsFormat,
    QuerySolutions,
    RdfFormat,
    parse,
    parse_query_results,
    serialize,
)

from segb_server.backend.store.base import (
    Bindings,
    QueryResult,
    Store,
    StoreError,
    StoreRejectedQuery,
    StoreUnavailable,
)
from segb_server.backend.store.terms import bind_values

logger = logging.getLogger("segb.store")

# Requests: one byte naming the operation, then its argument.
_QUERY, _APPLIED, _PING, _COUNT, _BATCHES = b"q", b"a", b"p", b"c", b"b"
# Answers: one byte naming what follows.
_SOLUTIONS, _TRIPLES, _VALUE, _CHUNK, _END, _REJECTED, _UNAVAILABLE = b"j", b"t", b"v", b"d", b"e", b"r", b"u"


@dataclass(frozen=True)
class ChannelAddress:
    """Where a store's channel listens, the key its connections prove they hold, and what the reader must know
    of the store without asking (its kind and graph, how it takes VALUES)."""

    path: str
    key: bytes
    kind: str
    graph_uri: str
    wraps_values: bool


class StoreChannel:
    """Serves `store`'s reads to this server's other processes, until closed. `niceness`: how much lower than
    this process's own threads the serving threads run (Linux, where a thread has a priority of its own)."""

    def __init__(self, store: Store, *, niceness: int = 0) -> None:
        self.store = store
        self.niceness = niceness
        self._folder: str | None = None
        if sys.platform == "linux":  # the key, not the name, keeps other local users out
            path = f"\0segb-store-{os.getpid()}-{secrets.token_hex(8)}"
        else:
            self._folder = tempfile.mkdtemp(prefix="segb-store-")  # 0700: this user's alone
            path = str(Path(self._folder) / "store.sock")  # a short path: a Unix socket's is at most 107 bytes
        self.address = ChannelAddress(path, secrets.token_bytes(32), store.kind, store.graph_uri, store.wraps_values)
        self._listener = Listener(path, family="AF_UNIX", authkey=self.address.key)
        self._connections: list[Connection] = []
        self._lock = threading.Lock()
        self._closed = False
        self._acceptor = threading.Thread(target=self._accept, name="segb-store-channel", daemon=True)
        self._acceptor.start()

    def close(self) -> None:
        with self._lock:
            self._closed = True
            connections, self._connections = self._connections, []
        # Closing a socket does not end an accept() waiting on it in another thread, which would keep the socket
        # (and its name) until the process ends: one last bare connection wakes it (its handshake fails at once) and
        # it sees the channel closed. Bare, and the wait bounded: a caller stalling a handshake must not hold shutdown.
        with contextlib.suppress(OSError), socket.socket(socket.AF_UNIX) as wake:
            wake.settimeout(1)
            wake.connect(self.address.path)
        self._acceptor.join(timeout=5)
        self._listener.close()
        for connection in connections:  # each serving thread then reads the end, and closes its connection
            _shut(connection)
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)

    def _accept(self) -> None:
        while True:
            try:
                connection = self._listener.accept()
            except OSError:  # closed
                return
            except Exception as error:  # a caller without the key, or one that went away mid-handshake
                if self._closed:  # the connection that wakes this thread when the channel closes
                    return
                logger.warning("a connection to the store's channel was refused: %s", error)
                continue
            with self._lock:
                if self._closed:
                    connection.close()
                    return
                self._connections.append(connection)
            threading.Thread(target=self._serve, args=(connection,), name="segb-store-reader", daemon=True).start()

    def _serve(self, connection: Connection) -> None:
        if self.niceness and sys.platform == "linux":  # elsewhere the call would lower the whole process
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), self.niceness)
        try:
            while True:
                request = connection.recv_bytes()
                try:
                    self._answer(connection, request[:1], request[1:])
                except StoreRejectedQuery as error:
                    connection.send_bytes(_REJECTED + str(error).encode())
                except (StoreError, OSError) as error:
                    connection.send_bytes(_UNAVAILABLE + str(error).encode())
                except Exception as error:  # a bug: the reader gets an answer all the same, and does not hang
                    logger.exception("the store's channel failed to answer")
                    connection.send_bytes(_UNAVAILABLE + f"{type(error).__name__}: {error}".encode())
        except (EOFError, OSError):  # the reader went away, or the channel closed
            pass
        finally:
            with self._lock:
                if connection in self._connections:
                    self._connections.remove(connection)
            connection.close()

    def _answer(self, connection: Connection, operation: bytes, argument: bytes) -> None:
        if operation == _QUERY:
            answer = self.store.query(argument.decode())
            if isinstance(answer, QuerySolutions | QueryBoolean):
                written = answer.serialize(format=QueryResultsFormat.JSON)
                connection.send_bytes(_SOLUTIONS + (written or b""))
            else:
                connection.send_bytes(_TRIPLES + (serialize(answer, format=RdfFormat.N_TRIPLES) or b""))
        elif operation == _APPLIED:
            through = self.store.applied_through()
            connection.send_bytes(_VALUE + (b"" if through is None else str(through).encode()))
        elif operation == _PING:
            self.store.ping()
            connection.send_bytes(_VALUE)
        elif operation == _COUNT:
            connection.send_bytes(_VALUE + str(self.store.count()).encode())
        elif operation == _BATCHES:
            for quads in self.store.batches(int(argument)):
                triples = [Quad(quad.subject, quad.predicate, quad.object) for quad in quads]
                connection.send_bytes(_CHUNK + (serialize(triples, format=RdfFormat.N_QUADS) or b""))
            connection.send_bytes(_END)
        else:
            raise StoreError(f"unknown request {operation!r} on the store's channel")


class ChannelStore:
    """The `Store` of a process that reads the embedded store through the channel of the process that opened it.
    It only reads: the applier writes in the process that opened the store."""

    remote = False  # its queries run on this machine's cores (the other process's), not across a network
    max_sorted_rows: int | None = None

    def __init__(self, address: ChannelAddress) -> None:
        self.address = address
        self.kind = address.kind
        self.graph_uri = address.graph_uri
        self.wraps_values = address.wraps_values
        self._local = threading.local()
        self._opened: list[Connection] = []
        self._lock = threading.Lock()

    def ping(self) -> None:
        self._ask(_PING)

    def applied_through(self) -> int | None:
        value = self._ask(_APPLIED)
        return int(value) if value else None

    def count(self) -> int:
        return int(self._ask(_COUNT))

    def query(self, sparql: str, bindings: Bindings | None = None, timeout: float | None = None) -> QueryResult:
        kind, body = self._request(_QUERY + bind_values(sparql, bindings).encode())
        if kind == _SOLUTIONS:
            return parse_query_results(body, QueryResultsFormat.JSON)
        return (quad.triple for quad in parse(body, RdfFormat.N_TRIPLES))

    def batches(self, size: int) -> Iterator[list[Quad]]:
        connection = self._connect()  # of its own: the answer comes in many messages
        try:
            connection.send_bytes(_BATCHES + str(size).encode())
            while True:
                kind, body = _read(connection)
                if kind == _END:
                    return
                yield [
                    Quad(quad.subject, quad.predicate, quad.object, DefaultGraph())
                    for quad in parse(body, RdfFormat.N_QUADS)
                ]
        except (EOFError, OSError) as error:
            raise StoreUnavailable(f"the store's channel closed: {error}") from error
        finally:
            connection.close()

    def apply(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        raise StoreError("the store is written by the process that opened it, not through its channel")

    def remove(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        raise StoreError("the store is written by the process that opened it, not through its channel")

    def clear(self, through: int | None = None, epoch: int | None = None) -> int:
        raise StoreError("the store is written by the process that opened it, not through its channel")

    def claim(self, epoch: int) -> None:
        raise StoreError("the store is written by the process that opened it, not through its channel")

    def close(self) -> None:
        with self._lock:
            opened, self._opened = self._opened, []
        for connection in opened:  # a thread still reading from one gets an outage, not a closed handle
            _shut(connection)

    def _ask(self, operation: bytes) -> bytes:
        return self._request(operation)[1]

    def _request(self, message: bytes) -> tuple[bytes, bytes]:
        connection = getattr(self._local, "connection", None)
        if connection is None:
            connection = self._local.connection = self._connect()
            with self._lock:
                self._opened.append(connection)
        try:
            connection.send_bytes(message)
            return _read(connection)
        except (EOFError, OSError) as error:  # the other process went away: a new connection next time
            self._local.connection = None
            with self._lock:  # whoever takes a connection off the list closes it, once
                mine = connection in self._opened
                if mine:
                    self._opened.remove(connection)
            if mine:
                connection.close()
            raise StoreUnavailable(f"the store's channel closed: {error}") from error

    def _connect(self) -> Connection:
        try:
            return Client(self.address.path, family="AF_UNIX", authkey=self.address.key)
        except (OSError, EOFError) as error:
            where = self.address.path.replace("\0", "@")  # an abstract name, as `ss -x` shows it
            raise StoreUnavailable(f"cannot reach the store's channel at {where}: {error}") from error


def _shut(connection: Connection) -> None:
    """End a connection's traffic both ways without closing its handle, which the thread using it may be reading
    from: that thread sees the connection end and closes it itself."""
    with contextlib.suppress(OSError), socket.socket(fileno=os.dup(connection.fileno())) as shared:
        shared.shutdown(socket.SHUT_RDWR)


def _read(connection: Connection) -> tuple[bytes, bytes]:
    """One answer: its kind and body; the store's own errors raised as they were raised in the other process."""
    answer = connection.recv_bytes()
    kind, body = answer[:1], answer[1:]
    if kind == _REJECTED:
        raise StoreRejectedQuery(body.decode())
    if kind == _UNAVAILABLE:
        raise StoreUnavailable(body.decode())
    return kind, body
