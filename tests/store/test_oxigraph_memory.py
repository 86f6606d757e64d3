"""The embedded store's memory is bounded: RocksDB's memory tables are flushed to its files every so many
applied triples, instead of growing with the store (pyoxigraph lets them reach about 1.5 GiB), while posts go
on being applied and erasures swap the store's files."""

from __future__ import annotations

import threading
import time
from pathlib import Path

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.store.oxigraph import OxigraphStore

EX = "http://example.org/"


def _post(index: int, triples: int = 50) -> list[Quad]:
    node = NamedNode(f"{EX}activity/{index}")
    return [Quad(node, NamedNode(f"{EX}p{n}"), Literal(f"value {index} {n}")) for n in range(triples)]


def _files(path: Path, suffix: str) -> int:
    """Bytes of the store's files with this suffix (.sst: flushed tables; .log: RocksDB's write-ahead log)."""
    return sum(file.stat().st_size for file in path.rglob(f"*{suffix}"))


def _settled(store: OxigraphStore) -> None:
    deadline = time.monotonic() + 30
    while store._flushing.locked() and time.monotonic() < deadline:  # a flush under way
        time.sleep(0.01)


def test_applied_triples_are_flushed_from_memory_every_so_many(tmp_path: Path) -> None:
    store = OxigraphStore("urn:test", tmp_path / "store", flush_every=2_000)
    unbounded = OxigraphStore("urn:test", tmp_path / "unbounded", flush_every=10**9)
    try:
        for index in range(200):  # 10,000 triples
            store.apply(_post(index), index + 1)
            unbounded.apply(_post(index), index + 1)
            # Each flush let finish before the next post: one is begun per 2,000 triples however slow the disk is
            # (one still running when the next is due covers those triples too, which a busy machine would show).
            _settled(store)
        assert store.flushes == 5
        assert unbounded.flushes == 0
        # Flushed: the tables are in RocksDB's files, and its log (what memory still holds) was started anew.
        sizes = {
            name: (_files(tmp_path / name, ".sst"), _files(tmp_path / name, ".log")) for name in ("store", "unbounded")
        }
        assert sizes["store"][0] > 10 * sizes["unbounded"][0], sizes
        assert sizes["store"][1] < sizes["unbounded"][1] * 0.75, sizes
        assert store.count() == unbounded.count() == 10_000
    finally:
        store.close()
        unbounded.close()


def test_flushes_run_beside_posts_and_erasures(tmp_path: Path) -> None:
    """A flush runs on a thread of its own while posts are applied, and an erasure that swaps the store's files
    waits for it: nothing is lost, and the store opens again whole."""
    path = tmp_path / "store"
    store = OxigraphStore("urn:test", path, flush_every=500)
    errors: list[BaseException] = []
    applied = [0]

    def post() -> None:
        try:
            for index in range(300):
                applied[0] = index + 1
                store.apply(_post(index, 10), index + 1)
        except BaseException as error:  # reported below, on the test thread
            errors.append(error)

    writer = threading.Thread(target=post)
    writer.start()
    erased = 0
    while writer.is_alive():
        if applied[0] > 20 * (erased + 1):
            store.remove(_post(erased * 20, 10), applied[0])  # one activity's triples erased, the store rewritten
            erased += 1
        time.sleep(0.005)
    writer.join()
    _settled(store)
    assert not errors
    assert store.flushes >= 3 and erased >= 2
    assert store.count() == 3_000 - 10 * erased
    store.close()
    reopened = OxigraphStore("urn:test", path)
    try:
        assert reopened.count() == 3_000 - 10 * erased
    finally:
        reopened.close()
