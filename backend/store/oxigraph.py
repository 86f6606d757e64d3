"""Embedded store on pyoxigraph (RocksDB on disk, or in memory); events live in its default graph."""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from itertools import islice
from pathlib import Path

from pyoxigraph import DefaultGraph, Quad, QuerySolutions
from pyoxigraph import Store as OxStore

from segb_server.backend.store.base import Bindings, QueryResult, StoreRejectedQuery, StoreUnavailable
from segb_server.backend.store.terms import bind_values

_COUNT = "SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }"


class OxigraphStore:
    """Keeping events in the default graph lets parsed quads be checked and inserted without rewrapping,
    which is most of the per-triple cost of a re-publish. Other named graphs stay free for server data."""

    def __init__(self, graph_uri: str, path: Path | None = None) -> None:
        self.kind = "oxigraph" if path is not None else "memory"
        self.graph_uri = graph_uri
        if path is not None:
            path.mkdir(parents=True, exist_ok=True)
            try:
                self._store = OxStore(str(path))
            except OSError as error:
                raise StoreUnavailable(f"cannot open the embedded store at {path}: {error}") from error
        else:
            self._store = OxStore()
        # Counting new triples exactly needs the check and the write to be one step per post.
        self._write_lock = threading.Lock()

    def ping(self) -> None:
        try:
            self._store.query("ASK {}")
        except OSError as error:
            raise StoreUnavailable(str(error)) from error

    def insert_new(self, quads: Sequence[Quad]) -> int:
        with self._write_lock:
            store = self._store
            new = list(dict.fromkeys(quad for quad in quads if quad not in store))
            if new:
                store.extend(new)
        return len(new)

    def clear(self) -> int:
        with self._write_lock:
            removed = self.count()
            self._store.clear_graph(DefaultGraph())
        return removed

    def count(self) -> int:
        solutions = self._store.query(_COUNT)
        assert isinstance(solutions, QuerySolutions)
        return int(next(iter(solutions))["n"].value)

    def query(self, sparql: str, bindings: Bindings | None = None, timeout: float | None = None) -> QueryResult:
        # pyoxigraph cannot cancel a query; it yields solutions lazily, so the caller's per-row deadline
        # is what bounds it (`timeout` is accepted for the protocol's sake).
        try:
            return self._store.query(bind_values(sparql, bindings))
        except SyntaxError as error:
            raise StoreRejectedQuery(str(error)) from error
        except OSError as error:
            raise StoreUnavailable(str(error)) from error

    def batches(self, size: int) -> Iterator[list[Quad]]:
        quads = self._store.quads_for_pattern(None, None, None, DefaultGraph())
        while batch := list(islice(quads, size)):
            yield batch

    def close(self) -> None:
        self._store.flush()
        del self._store
