"""Group commit with real threads: a lone item commits at once, items arriving during a commit are written
together by the next one, each caller gets its own outcome, and `exclusive()` holds commits back."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from segb_server.backend.services.ingest.group_commit import GroupCommit


class Recorder:
    """A commit function that records its batches; the first batch can be held until released."""

    def __init__(self, hold_first: bool = False) -> None:
        self.batches: list[list[int]] = []
        self.started = threading.Event()
        self.release = threading.Event()
        if not hold_first:
            self.release.set()

    def __call__(self, items: list[int]) -> list[int | BaseException]:
        self.batches.append(list(items))
        self.started.set()
        self.release.wait(10)
        return [ValueError(f"item {item} refused") if item < 0 else item * 10 for item in items]


def wait_until(condition, timeout: float = 10) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "condition not reached in time"
        time.sleep(0.005)


def test_a_lone_item_is_committed_at_once() -> None:
    recorder = Recorder()
    writer = GroupCommit(recorder)

    assert writer.submit(3) == 30
    assert writer.submit(4) == 40
    assert recorder.batches == [[3], [4]]


def test_items_arriving_during_a_commit_are_committed_together_each_with_its_own_outcome() -> None:
    recorder = Recorder(hold_first=True)
    writer = GroupCommit(recorder)
    with ThreadPoolExecutor(max_workers=9) as pool:
        first = pool.submit(writer.submit, 0)
        assert recorder.started.wait(10)
        waiting = {item: pool.submit(writer.submit, item) for item in range(1, 9)}
        wait_until(lambda: len(writer._pending) == 8)
        assert not any(future.done() for future in waiting.values())  # nobody answered before its commit
        recorder.release.set()
        outcomes = {item: future.result(10) for item, future in waiting.items()}

    assert first.result() == 0
    assert outcomes == {item: item * 10 for item in range(1, 9)}
    assert recorder.batches[0] == [0]
    assert sorted(recorder.batches[1]) == list(range(1, 9))  # one commit for all eight
    assert len(recorder.batches) == 2


def test_an_item_that_fails_raises_for_its_caller_only() -> None:
    recorder = Recorder(hold_first=True)
    writer = GroupCommit(recorder)
    with ThreadPoolExecutor(max_workers=3) as pool:
        pool.submit(writer.submit, 0)
        assert recorder.started.wait(10)
        bad, good = pool.submit(writer.submit, -1), pool.submit(writer.submit, 2)
        wait_until(lambda: len(writer._pending) == 2)
        recorder.release.set()
        with pytest.raises(ValueError, match="item -1 refused"):
            bad.result(10)
        assert good.result(10) == 20
    assert sorted(recorder.batches[1]) == [-1, 2]


def test_a_failing_commit_raises_for_every_item_of_its_batch() -> None:
    def broken(items: list[int]) -> list[int | BaseException]:
        raise OSError("disk full")

    writer = GroupCommit(broken)
    with pytest.raises(OSError, match="disk full"):
        writer.submit(1)


def test_exclusive_holds_commits_back_until_it_ends() -> None:
    recorder = Recorder()
    writer = GroupCommit(recorder)
    with ThreadPoolExecutor(max_workers=1) as pool:
        with writer.exclusive():
            pending = pool.submit(writer.submit, 5)
            wait_until(lambda: len(writer._pending) == 1)
            time.sleep(0.05)
            assert recorder.batches == [] and not pending.done()
        assert pending.result(10) == 50
    assert recorder.batches == [[5]]
