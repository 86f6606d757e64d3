"""A bounded memory of triples known to be in a remote store, so re-published triples cost no round trip."""

from __future__ import annotations

import threading
from collections.abc import Iterable
from hashlib import blake2b


def triple_key(ntriples_line: str) -> int:
    """128-bit digest of a triple's N-Triples text: at a million entries a false match is ~1e-26 likely."""
    return int.from_bytes(blake2b(ntriples_line.encode("utf-8"), digest_size=16).digest(), "big")


class KnownTriples:
    """Digests of triples this server wrote to (or found in) the store.

    It only ever answers "known" for triples that were really there, so a wrong answer needs someone else
    to delete triples behind the server's back; `forget()` is called on delete-all and after the store
    comes back from an outage. When full it starts over, which costs round trips, never correctness.
    """

    def __init__(self, capacity: int) -> None:
        self._capacity = capacity
        self._keys: set[int] = set()
        self._lock = threading.Lock()

    def __contains__(self, key: int) -> bool:
        return key in self._keys

    def __len__(self) -> int:
        return len(self._keys)

    def remember(self, keys: Iterable[int]) -> None:
        with self._lock:
            self._keys.update(keys)
            if len(self._keys) > self._capacity:
                self._keys = set()

    def forget(self) -> None:
        with self._lock:
            self._keys = set()
