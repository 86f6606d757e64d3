"""Digests of triples the journal is known to hold, so that a re-published triple costs no database lookup —
kept to the most recently seen, so that memory does not grow with a robot's history.

The PyPI client re-sends its whole accumulated graph on every publish: most of a post's triples were in the
previous one. Remembering every digest since the last clearing made the server's memory grow by about 90 bytes
per triple the robot ever logged (90 MiB a million triples, without end for a robot that runs for months). Two
generations instead: digests go into the current one; when it is full, it becomes the previous one and the one
before is dropped; a digest found in the previous generation moves to the current one. So whatever a client
re-sends, post after post, stays remembered, and at most twice `generation` digests are. A digest that is not
remembered is looked up in the journal's table of digests, which decides: forgetting costs time, never a triple.
"""

from __future__ import annotations

from collections.abc import Iterable

GENERATION = 300_000  # digests per generation: at most about 55 MiB for both


class KnownDigests:
    def __init__(self, generation: int | None = None) -> None:
        self._generation = generation or GENERATION
        self._current: set[bytes] = set()
        self._previous: set[bytes] = set()

    def __contains__(self, digest: object) -> bool:
        if digest in self._current:
            return True
        if isinstance(digest, bytes) and digest in self._previous:
            self._add(digest)  # still re-sent: kept for the next generation too
            return True
        return False

    def __len__(self) -> int:
        return len(self._current) + len(self._previous)

    def update(self, digests: Iterable[bytes]) -> None:
        for digest in digests:
            self._add(digest)

    def _add(self, digest: bytes) -> None:
        self._current.add(digest)
        if len(self._current) >= self._generation:
            self._previous, self._current = self._current, set()
