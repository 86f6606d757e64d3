"""A process that runs users' SPARQL over a snapshot of the embedded store, so the server can stop a query at
its deadline, or past its memory limit, by ending the process — the embedded store cannot interrupt a query
running in a thread, and a runaway query must not take the server's memory.

Spoken to over a pipe: `Ask` in, `Answer` out. A snapshot is a RocksDB checkpoint directory opened read-only,
or (for an in-memory store) N-Quads to load; the last one opened stays open for the next query.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import islice
from multiprocessing.connection import Connection
from typing import Literal

from pyoxigraph import (
    QueryBoolean,
    QueryResultsFormat,
    QuerySolution,
    QuerySolutions,
    RdfFormat,
    Store,
    Variable,
    serialize,
)

from segb_server.backend.services.sparql.limits import solutions_of

AnswerKind = Literal["solutions", "boolean", "graph", "error"]


@dataclass(frozen=True)
class Ask:
    snapshot: str  # identifies the snapshot; the same id means the same data
    path: str | None  # a checkpoint directory, or None with `nquads`
    nquads: bytes | None  # the data of an in-memory store, sent only when the worker lacks it
    query: str
    max_rows: int


@dataclass(frozen=True)
class Answer:
    kind: AnswerKind
    payload: bytes  # SPARQL JSON results, or N-Triples for a graph; the message for an error
    truncated: bool = False
    rows: int = 0


def serve(connection: Connection) -> None:
    """The worker's main loop (the target of its process)."""
    opened: tuple[str, Store] | None = None
    while True:
        try:
            ask: Ask = connection.recv()
        except EOFError:
            return
        try:
            if opened is None or opened[0] != ask.snapshot:
                opened = None  # drop the old snapshot before opening the next
                opened = (ask.snapshot, _open(ask))
            answer = _answer(opened[1], ask)
        except MemoryError:
            answer = Answer("error", b"memory")
        except SyntaxError as error:
            answer = Answer("error", f"syntax: {error}".encode())
        except OSError as error:
            answer = Answer("error", f"store: {error}".encode())
        connection.send(answer)


def _open(ask: Ask) -> Store:
    if ask.path is not None:
        return Store.read_only(ask.path)
    store = Store()
    if ask.nquads:
        store.load(ask.nquads, RdfFormat.N_QUADS)
    return store


def _answer(store: Store, ask: Ask) -> Answer:
    result = store.query(ask.query)
    if isinstance(result, QueryBoolean):
        return Answer("boolean", _written(result.serialize(format=QueryResultsFormat.JSON)))
    wanted = ask.max_rows + 1  # one more than allowed tells whether there were more
    if isinstance(result, QuerySolutions):
        variables = result.variables
        rows = list(islice(result, wanted))
        kept = rows[: ask.max_rows]
        return Answer("solutions", _solutions_json(variables, kept), len(rows) > len(kept), len(kept))
    triples = list(islice(result, wanted))
    kept_triples = triples[: ask.max_rows]
    written = _written(serialize(kept_triples, format=RdfFormat.N_TRIPLES))
    return Answer("graph", written, len(triples) > len(kept_triples), len(kept_triples))


def _written(data: bytes | None) -> bytes:
    assert data is not None  # without an output file, pyoxigraph returns the bytes
    return data


def _solutions_json(variables: Sequence[Variable], rows: Sequence[QuerySolution]) -> bytes:
    """Rows as SPARQL JSON results, through pyoxigraph's own writer."""
    return _written(solutions_of(variables, rows).serialize(format=QueryResultsFormat.JSON))
