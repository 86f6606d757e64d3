"""Results derived from the events graph (report pages, the drawable graph), kept until the graph changes.

Reads far outnumber writes in an audit, and a report over 100k triples costs the embedded store 100-250 ms.
Every write the journal's applier makes bumps `DataVersion`, which drops every cached result. Only a store
this process owns can be cached this way: another writer to a shared Virtuoso would go unnoticed, so the
cache is off for remote stores.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import TypeVar

T = TypeVar("T")


class DataVersion:
    """A counter of writes to the events graph made through this server."""

    def __init__(self) -> None:
        self._value = 0
        self._lock = threading.Lock()

    @property
    def value(self) -> int:
        return self._value

    def bump(self) -> None:
        with self._lock:
            self._value += 1


class ResultCache:
    """A bounded LRU of results, valid for one data version."""

    def __init__(self, version: DataVersion, *, enabled: bool, size: int = 128) -> None:
        self._version = version
        self._enabled = enabled
        self._size = size
        self._entries: OrderedDict[Hashable, T] = OrderedDict()  # type: ignore[valid-type]
        self._seen_version = version.value
        self._lock = threading.Lock()

    def get(self, key: Hashable, compute: Callable[[], T]) -> T:
        if not self._enabled:
            return compute()
        with self._lock:
            if self._seen_version != self._version.value:
                self._entries.clear()
                self._seen_version = self._version.value
            if key in self._entries:
                self._entries.move_to_end(key)
                return self._entries[key]
        version = self._version.value
        result = compute()  # outside the lock: a slow query must not hold up cached readers
        with self._lock:
            # A write during the computation may have made the result stale: then it is not kept.
            if version == self._version.value == self._seen_version:
                self._entries[key] = result
                if len(self._entries) > self._size:
                    self._entries.popitem(last=False)
        return result
