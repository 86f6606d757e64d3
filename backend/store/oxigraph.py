"""Embedded store on pyoxigraph (RocksDB on disk, or in memory); events live in its default graph."""

from __future__ import annotations

import logging
import os
import queue
import shutil
import threading
import uuid
from collections.abc import Callable, Iterator, Sequence
from itertools import islice
from pathlib import Path

from pyoxigraph import DefaultGraph, Literal, NamedNode, Quad, QuerySolutions, RdfFormat
from pyoxigraph import Store as OxStore

from segb_server.backend.store.base import (
    CURSOR_PREDICATE,
    CURSOR_SUBJECT,
    EPOCH_PREDICATE,
    Bindings,
    QueryResult,
    StoreFenced,
    StoreRejectedQuery,
    StoreUnavailable,
)
from segb_server.backend.store.terms import bind_values

_COUNT = "SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }"
# RocksDB keeps what is written in memory tables until it flushes them to its files; pyoxigraph gives each of its
# twelve column families 128 MiB of them, so left alone the server's memory grows with the store (about 0.26 MiB
# per 1,000 triples of a robot's log) up to about 1.5 GiB. A flush after every MEMTABLE_FLUSH_TRIPLES applied
# triples bounds them to about 100 MiB; it runs on a thread of its own, without the interpreter lock, while
# applying goes on (100,000 triples' tables in about 0.2 s). Not fewer: the views read back what posts just added,
# and those reads are cheapest in memory. Flushing every 100,000 triples, the soak's views fell 10 s behind (p99)
# where every 400,000 they stayed within 3.6 s (bench/soak.py, one robot, 3 minutes).
MEMTABLE_FLUSH_TRIPLES = 400_000
# The cursor's graph here; queries see only the default graph.
CURSOR_GRAPH = NamedNode("urn:segb:applied")
XSD_INTEGER = NamedNode("http://www.w3.org/2001/XMLSchema#integer")
logger = logging.getLogger("segb.store")


class OxigraphStore:
    """Keeping events in the default graph lets parsed quads be checked and inserted without rewrapping,
    which is most of the per-triple cost of a re-publish. Other named graphs stay free for server data."""

    wraps_values = False
    max_sorted_rows: int | None = None
    remote = False

    def __init__(self, graph_uri: str, path: Path | None = None, flush_every: int = MEMTABLE_FLUSH_TRIPLES) -> None:
        self.kind = "oxigraph" if path is not None else "memory"
        self.graph_uri = graph_uri
        self.path = path
        self.live: Path | None = None  # the directory the store is in (see `live_directory`)
        if path is not None:
            finish_rewrite(path)
            self.live = live_directory(path)
            self.live.mkdir(parents=True, exist_ok=True)
            try:
                self._store = OxStore(str(self.live))
            except OSError as error:
                if "LOCK" in str(error):
                    raise StoreUnavailable(
                        f"another SEGB server is using the embedded store at {path}: stop it, or read its data "
                        "through that server (GET /events)"
                    ) from None
                raise StoreUnavailable(f"cannot open the embedded store at {path}: {error}") from error
            tidy_generations(path, self.live)  # only now: holding the store's lock, no other process uses them
        else:
            self._store = OxStore()
        self._write_lock = threading.Lock()
        self._flush_every = flush_every
        self._unflushed = 0  # triples applied since the last flush began
        self._flushing = threading.Lock()  # held while a flush runs: a swap of the store or a close waits for it
        self.flushes = 0  # flushes begun (the memory bound's own count)
        self._applied = self._read_cursor()
        self._epoch = self._read_epoch()

    def ping(self) -> None:
        try:
            self._store.query("ASK {}")
        except OSError as error:
            raise StoreUnavailable(str(error)) from error

    def apply(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        # One `extend` is one transaction: the triples and the new cursor are committed together. Every writer
        # is in this process (one process opens the store), so the epoch checked under the write lock is final.
        with self._write_lock:
            newer = self._epoch_to_write(epoch)
            self._store.extend([*quads, _cursor(through), *newer])
            self._drop_cursor_unless(through)
            self._epoch_written(epoch)
            self._unflushed += len(quads)
            due = self.path is not None and self._unflushed >= self._flush_every
            if due and self._flushing.acquire(blocking=False):  # one at a time: a flush under way covers these too
                self._unflushed = 0
                self.flushes += 1
                threading.Thread(target=self._flush, name="store-flush", daemon=True).start()

    def _flush(self) -> None:
        try:
            self._store.flush()
        except OSError as error:  # the triples are in RocksDB's log: a later flush or the next start writes them
            logger.warning("the store's memory tables could not be flushed: %s", error)
        finally:
            self._flushing.release()

    def remove(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        """On disk, the store is written anew without the quads: RocksDB and the store's string table keep a
        removed literal's text in their files otherwise (the store never deletes a string it once held). The
        copy is made beside the store, its cursor included, and swapped in whole (finish_rewrite), so a crash
        leaves the old store, erasure not applied, or the new one."""
        with self._write_lock:
            self._epoch_to_write(epoch)
            gone = set(_spelt_by_the_store(quads))
            if self.path is None or not gone:
                for quad in gone:
                    self._store.remove(quad)
                self._set_cursor(through, epoch)
                return
            fresh = self.path.with_name(self.path.name + REWRITING)
            shutil.rmtree(fresh, ignore_errors=True)
            copy = OxStore(str(fresh))
            copy.bulk_extend(quad for quad in self._store if quad not in gone and quad.graph_name != CURSOR_GRAPH)
            kept_epoch = self._epoch if epoch is None else epoch
            copy.extend([_cursor(through), *([] if kept_epoch is None else [_epoch(kept_epoch)])])
            copy.flush()
            self._applied, self._epoch = through, kept_epoch
            del copy
            # The copy never takes the old store's path: RocksDB names its files by path, and the old store stays
            # open while a reader still holds it (a query's answer, an export) — what it then writes or deletes
            # (a compaction's inputs, a new MANIFEST) must not land among the copy's files, numbered alike. The
            # copy gets a directory of its own, named in the pointer file, whose writing is the commit point.
            generation = self.path.with_name(f"{self.path.name}{GENERATION}{uuid.uuid4().hex[:12]}")
            fresh.rename(generation)
            point_to(self.path, generation)
            old, self.live = self.live or self.path, generation
            with self._flushing:  # a flush of the old store ends before its files go
                self._store = OxStore(str(generation))
                shutil.rmtree(old, ignore_errors=True)  # its text leaves the disk (open files: once their readers end)

    def _set_cursor(self, through: int, epoch: int | None) -> None:
        self._store.extend([_cursor(through), *self._epoch_to_write(epoch)])
        self._drop_cursor_unless(through)
        self._epoch_written(epoch)

    def claim(self, epoch: int) -> None:
        with self._write_lock:
            self._record_epoch(epoch)

    def _record_epoch(self, epoch: int | None) -> None:
        self._store.extend(self._epoch_to_write(epoch))
        self._epoch_written(epoch)

    def _epoch_to_write(self, epoch: int | None) -> list[Quad]:
        """Under the write lock: StoreFenced for an epoch older than the store's; the quad recording a newer one."""
        if epoch is None or epoch == self._epoch:
            return []
        if self._epoch is not None and epoch < self._epoch:
            raise StoreFenced(epoch, self._epoch)
        return [_epoch(epoch)]

    def _epoch_written(self, epoch: int | None) -> None:
        """The quad of `epoch` is written (if new): the one before goes."""
        if epoch is not None and epoch != self._epoch:
            if self._epoch is not None:
                self._store.remove(_epoch(self._epoch))
            self._epoch = epoch

    def _drop_cursor_unless(self, through: int) -> None:
        """The cursor is now `through` (its quad written): the one before goes. The store's cursor is kept in
        memory too: this process alone writes the store, and reading it back was a twentieth of a small post's
        time (and is what the views' process asks most often)."""
        if self._applied is not None and self._applied != through:
            self._store.remove(_cursor(self._applied))
        self._applied = through

    def clear(self, through: int | None = None, epoch: int | None = None) -> int:
        with self._write_lock:
            self._epoch_to_write(epoch)
            removed = self.count()
            self._store.clear_graph(DefaultGraph())
            if through is not None:
                self._set_cursor(through, epoch)
            else:
                self._record_epoch(epoch)
        return removed

    def checkpoint(self, target: Path) -> None:
        """A consistent copy at `target` that another process can open read-only (hard links: cheap)."""
        self._store.backup(str(target))

    def dump_nquads(self) -> bytes:
        """Every quad, for a copy of an in-memory store (which has no files to share)."""
        written = self._store.dump(format=RdfFormat.N_QUADS)
        assert written is not None
        return written

    def applied_through(self) -> int | None:
        return self._applied

    def _read_cursor(self) -> int | None:
        """The cursor the store holds (the latest, should a crash have left two), alone from now on."""
        quads = list(self._store.quads_for_pattern(CURSOR_SUBJECT, CURSOR_PREDICATE, None, CURSOR_GRAPH))
        cursors = sorted(int(quad.object.value) for quad in quads if isinstance(quad.object, Literal))
        for stale in cursors[:-1]:
            self._store.remove(_cursor(stale))
        return cursors[-1] if cursors else None

    def _read_epoch(self) -> int | None:
        """The newest apply epoch that wrote the store (the latest, should a crash have left two)."""
        quads = self._store.quads_for_pattern(CURSOR_SUBJECT, EPOCH_PREDICATE, None, CURSOR_GRAPH)
        epochs = [int(quad.object.value) for quad in quads if isinstance(quad.object, Literal)]
        return max(epochs, default=None)

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
        """pyoxigraph's iterators are unsendable (resumed on another thread, they abort the process), while an
        export is resumed by whichever worker thread writes the answer's next chunk: one thread of its own
        reads the store and hands the batches over."""
        return read_on_one_thread(lambda: self._store.quads_for_pattern(None, None, None, DefaultGraph()), size)

    def close(self) -> None:
        with self._flushing:
            self._store.flush()
            del self._store


_END = object()
REWRITING = ".rewriting"  # a copy being written (dropped if found at start: the old store is whole)
REWRITTEN = ".rewritten"  # a finished copy of an earlier version, to be swapped in
GENERATION = ".gen-"  # a finished copy in a directory of its own: the store once the pointer names it
POINTER = ".current"  # a file naming the directory the store is in, when it is not `path` itself


def live_directory(path: Path) -> Path:
    """The directory the store at `path` is in: `path`, or the copy the pointer file names."""
    pointer = path.with_name(path.name + POINTER)
    if pointer.is_file():
        named = path.with_name(pointer.read_text(encoding="utf-8").strip())
        if named.is_dir():
            return named
    return path


def point_to(path: Path, generation: Path) -> None:
    """Name `generation` as the store's directory, atomically and durably (the rewrite's commit point)."""
    pointer = path.with_name(path.name + POINTER)
    written = pointer.with_name(pointer.name + ".tmp")
    with written.open("w", encoding="utf-8") as out:
        out.write(generation.name)
        out.flush()
        os.fsync(out.fileno())
    written.replace(pointer)
    directory = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)


def tidy_generations(path: Path, live: Path) -> None:
    """Remove what an earlier rewrite left: copies unfinished or replaced, and the store's first directory once
    a copy has replaced it."""
    shutil.rmtree(path.with_name(path.name + REWRITING), ignore_errors=True)
    for directory in path.parent.glob(f"{path.name}{GENERATION}*"):
        if directory != live:
            shutil.rmtree(directory, ignore_errors=True)
    if live != path:
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.with_name(path.name + POINTER).unlink(missing_ok=True)


def finish_rewrite(path: Path) -> None:
    """Complete a rewrite of an earlier version that a crash interrupted: its finished copy replaces the store."""
    rewritten = path.with_name(path.name + REWRITTEN)
    old = path.with_name(path.name + ".old")
    if rewritten.is_dir():
        if path.exists():
            path.rename(old)
        rewritten.rename(path)
    shutil.rmtree(old, ignore_errors=True)


def _spelt_by_the_store(quads: Sequence[Quad]) -> Iterator[Quad]:
    """The quads as the store spells them (it keeps typed literals in canonical form: "8.7e-01" as "0.87"), in
    the default graph."""
    scratch = OxStore()
    scratch.extend(Quad(q.subject, q.predicate, q.object, DefaultGraph()) for q in quads)
    return iter(scratch)


def read_on_one_thread(open_quads: Callable[[], Iterator[Quad]], size: int) -> Iterator[list[Quad]]:
    """Batches of `size` quads from the iterator `open_quads` makes, read on a thread that owns it; two batches
    ahead at most. Closing the returned generator (a client gone) stops the reader."""
    handover: queue.Queue[object] = queue.Queue(maxsize=2)
    stopped = threading.Event()

    def hand_over(item: object) -> bool:
        while not stopped.is_set():
            try:
                handover.put(item, timeout=0.2)
                return True
            except queue.Full:
                continue
        return False

    def read() -> None:
        try:
            quads = open_quads()
            while batch := list(islice(quads, size)):
                if not hand_over(batch):
                    return
            hand_over(_END)
        except Exception as error:  # raised to the reader of the batches
            hand_over(error)

    def batches() -> Iterator[list[Quad]]:
        reader = threading.Thread(target=read, name="segb-store-reader", daemon=True)
        reader.start()
        try:
            while (item := handover.get()) is not _END:
                if isinstance(item, Exception):
                    raise item
                yield item  # type: ignore[misc]
        finally:
            stopped.set()

    return batches()


def _cursor(through: int) -> Quad:
    return Quad(CURSOR_SUBJECT, CURSOR_PREDICATE, Literal(str(through), datatype=XSD_INTEGER), CURSOR_GRAPH)


def _epoch(epoch: int) -> Quad:
    return Quad(CURSOR_SUBJECT, EPOCH_PREDICATE, Literal(str(epoch), datatype=XSD_INTEGER), CURSOR_GRAPH)
