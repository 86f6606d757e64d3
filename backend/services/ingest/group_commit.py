"""Group commit: concurrent callers' writes done together by one of them, each caller waiting for its own."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Generic, TypeVar

T = TypeVar("T")
R = TypeVar("R")


class _Slot(Generic[T, R]):
    def __init__(self, item: T) -> None:
        self.item = item
        self.done = False
        self.outcome: R | BaseException | None = None


class GroupCommit(Generic[T, R]):
    """`submit(item)` returns once `commit` has run over a batch holding the item.

    Whoever takes the commit lock commits every item waiting at that moment, its own included; a caller
    whose item a previous leader already committed just collects the outcome. So under load one thread
    writes many items with one store pass and one ledger transaction, while a lone caller commits at once.
    `commit` returns one outcome per item, a result or the exception that item's caller gets.
    """

    def __init__(self, commit: Callable[[list[T]], list[R | BaseException]]) -> None:
        self._commit = commit
        self._pending: list[_Slot[T, R]] = []
        self._pending_lock = threading.Lock()
        self._commit_lock = threading.Lock()

    def submit(self, item: T) -> R:
        slot: _Slot[T, R] = _Slot(item)
        with self._pending_lock:
            self._pending.append(slot)
        with self._commit_lock:
            if not slot.done:
                with self._pending_lock:
                    batch, self._pending = self._pending, []
                self._run(batch)
        if isinstance(slot.outcome, BaseException):
            raise slot.outcome
        return slot.outcome  # type: ignore[return-value]

    @contextmanager
    def exclusive(self) -> Iterator[None]:
        """No commit runs inside this block (for writes that must not interleave with a batch)."""
        with self._commit_lock:
            yield

    def _run(self, batch: list[_Slot[T, R]]) -> None:
        try:
            outcomes = self._commit([slot.item for slot in batch])
        except BaseException as error:  # the whole batch failed: every caller in it gets the error
            outcomes = [error] * len(batch)
        for slot, outcome in zip(batch, outcomes, strict=True):
            slot.outcome = outcome
            slot.done = True
