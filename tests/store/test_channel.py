"""The embedded store read through its channel answers as the store itself does, from several threads at once,
and refuses what it cannot do: writes, callers without the key, a store gone away."""

from __future__ import annotations

import os
import socket
import stat
import sys
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from multiprocessing.connection import AuthenticationError, Client
from pathlib import Path

import pytest
from pyoxigraph import Literal, NamedNode, Quad, QueryBoolean

from segb_server.backend.services.views.channel import ChannelStore, StoreChannel
from segb_server.backend.store.base import StoreError, StoreRejectedQuery, StoreUnavailable, select
from segb_server.backend.store.oxigraph import OxigraphStore

EX = "http://example.org/"
Opened = tuple[OxigraphStore, StoreChannel, ChannelStore]  # the store, its channel, and a reader through it


def _quads(count: int) -> list[Quad]:
    return [Quad(NamedNode(f"{EX}m{i}"), NamedNode(f"{EX}text"), Literal(f"hello {i}", language="en"))
            for i in range(count)]  # fmt: skip


@pytest.fixture
def opened(tmp_path: Path) -> Iterator[Opened]:
    store = OxigraphStore("urn:segb:events", tmp_path / "store")
    store.apply(_quads(250), through=7)
    channel = StoreChannel(store)
    reader = ChannelStore(channel.address)
    yield store, channel, reader
    reader.close()
    channel.close()
    store.close()


def test_a_select_through_the_channel_answers_as_the_store(opened: Opened) -> None:
    store, _, reader = opened
    query = f"SELECT ?m ?t WHERE {{ ?m <{EX}text> ?t }} ORDER BY ?m"
    assert select(reader, query) == select(store, query)
    bound = select(reader, f"SELECT ?t WHERE {{ ?m <{EX}text> ?t }}", {"m": NamedNode(f"{EX}m3")})
    assert bound.rows == [{"t": Literal("hello 3", language="en")}]


def test_ask_construct_count_and_cursor_through_the_channel(opened: Opened) -> None:
    store, _, reader = opened
    answer = reader.query(f"ASK {{ <{EX}m1> ?p ?o }}")
    assert isinstance(answer, QueryBoolean) and bool(answer)
    assert not bool(reader.query(f"ASK {{ <{EX}nobody> ?p ?o }}"))  # type: ignore[arg-type]
    built = list(reader.query(f"CONSTRUCT {{ ?m <{EX}said> ?t }} WHERE {{ ?m <{EX}text> ?t }}"))  # type: ignore[arg-type]
    assert len(built) == 250 and all(triple.predicate == NamedNode(f"{EX}said") for triple in built)
    assert reader.count() == store.count() == 250
    assert reader.applied_through() == 7
    store.apply(_quads(260)[250:], through=9)
    assert reader.applied_through() == 9  # the store as it is now, not as it was when the channel opened
    reader.ping()


def test_the_store_is_streamed_whole_in_batches(opened: Opened) -> None:
    store, _, reader = opened
    batches = list(reader.batches(100))
    assert [len(batch) for batch in batches] == [100, 100, 50]
    assert {quad for batch in batches for quad in batch} == {quad for batch in store.batches(100) for quad in batch}


def test_threads_read_side_by_side_each_on_its_own_connection(opened: Opened) -> None:
    _, _, reader = opened

    def ask(index: int) -> list[dict[str, object]]:
        return select(reader, f"SELECT ?t WHERE {{ <{EX}m{index}> <{EX}text> ?t }}").rows  # type: ignore[return-value]

    with ThreadPoolExecutor(8) as pool:
        answers = list(pool.map(ask, range(200)))
    assert answers == [[{"t": Literal(f"hello {i}", language="en")}] for i in range(200)]


def test_a_bad_query_is_refused_as_the_store_refuses_it_and_the_connection_serves_on(
    opened: Opened,
) -> None:
    _, _, reader = opened
    with pytest.raises(StoreRejectedQuery):
        reader.query("SELECT ?x WHERE { ?x")
    assert reader.count() == 250


def test_nothing_is_written_through_the_channel(opened: Opened) -> None:
    store, _, reader = opened
    for write in (lambda: reader.apply(_quads(1), 8), lambda: reader.remove(_quads(1), 8), lambda: reader.clear(8)):
        with pytest.raises(StoreError, match="written by the process that opened it"):
            write()
    assert store.count() == 250 and store.applied_through() == 7


def test_the_socket_leaves_no_file_behind_and_a_caller_without_the_key_is_refused(
    opened: Opened,
) -> None:
    """On Linux the socket's name is abstract (a SIGKILLed server leaves no file); elsewhere it is a file in a
    folder of this user's alone. Either way, the key is what lets a caller in."""
    _, channel, reader = opened
    if sys.platform == "linux":
        assert channel.address.path.startswith("\0")
    else:
        assert stat.S_IMODE(os.stat(Path(channel.address.path).parent).st_mode) == 0o700
    with pytest.raises(AuthenticationError):
        Client(channel.address.path, family="AF_UNIX", authkey=b"not the key")
    assert reader.count() == 250  # the channel serves on


@pytest.mark.skipif(sys.platform != "linux", reason="a thread has a priority of its own on Linux")
def test_the_channel_answers_below_this_process_priority(tmp_path: Path) -> None:
    store = OxigraphStore("urn:segb:events", tmp_path / "store")
    channel = StoreChannel(store, niceness=7)
    reader = ChannelStore(channel.address)
    try:
        assert reader.count() == 0  # a connection, and its serving thread
        serving = [thread for thread in threading.enumerate() if thread.name == "segb-store-reader"]
        assert serving
        for thread in serving:
            stat = Path(f"/proc/self/task/{thread.native_id}/stat").read_text()
            assert int(stat.rsplit(")", 1)[1].split()[16]) == os.getpriority(os.PRIO_PROCESS, 0) + 7
    finally:
        reader.close()
        channel.close()
        store.close()


def test_a_closed_channel_is_an_unavailable_store(tmp_path: Path) -> None:
    store = OxigraphStore("urn:segb:events", tmp_path / "store")
    channel = StoreChannel(store)
    reader = ChannelStore(channel.address)
    try:
        assert reader.count() == 0
        channel.close()
        if channel.address.path.startswith("\0"):  # the abstract name is free again
            with socket.socket(socket.AF_UNIX) as again:
                again.bind(channel.address.path)
        else:
            assert not Path(channel.address.path).exists()
        with pytest.raises(StoreUnavailable):
            reader.count()
        with pytest.raises(StoreUnavailable):
            reader.ping()
    finally:
        reader.close()
        store.close()


def test_a_caller_stalling_its_handshake_does_not_hold_the_channel_closing(tmp_path: Path) -> None:
    """A local connection that never answers the key's challenge holds the accepting thread; closing the channel
    (the server's shutdown) still ends within its bounded wait."""
    store = OxigraphStore("urn:segb:events", tmp_path / "store")
    channel = StoreChannel(store)
    stalling = socket.socket(socket.AF_UNIX)
    try:
        stalling.connect(channel.address.path)  # and says nothing
        closing = threading.Thread(target=channel.close, daemon=True)
        closing.start()
        closing.join(timeout=15)
        assert not closing.is_alive()
    finally:
        stalling.close()
        store.close()
