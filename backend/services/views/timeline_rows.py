"""Reading one kind's kept query from a position, a chunk of rows at a time: from its kept rows (keyset), or, while
they are being built, from the query's answer (by offset)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from segb_server.backend.services.errors import Conflict, ViewNotReady
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX
from segb_server.backend.services.sparql.paging import evaluated_page
from segb_server.backend.services.timeline.events import Row, TimelineEvent, event_of, json_rows
from segb_server.backend.store.base import Bindings

if TYPE_CHECKING:
    from segb_server.backend.services.timeline.sources import KeptSource

# A position in a source: {"after": cursor} in its kept rows, {"offset": n} in its query's answer, None for its
# first event.
Position = dict[str, str | int] | None
MAX_CHUNK = 5_000  # rows read at once at most (each read doubles the one before)


class Moved(Exception):
    """A source's rows changed between two reads of one page: the page is read again."""


@dataclass
class _Chunk:
    start: Position  # where its rows were read from
    rows: list[Row]
    next: Position  # where the rows after it start
    last: bool  # no rows after it


@dataclass
class KeptReader:
    """A kept source's events from a position, read a chunk of rows at a time. An event is a run of rows with one
    key and one time, so a chunk that ends inside an event is followed by the next before it is told."""

    source: KeptSource
    bindings: Bindings
    start: Position
    chunk: int
    served_from: str = "rows"
    chunks: list[_Chunk] = field(default_factory=list)
    at: tuple[int, int] = (0, 0)  # the next row not taken: (chunk, row)
    _peeked: tuple[TimelineEvent, tuple[int, int]] | None = None
    _done: bool = False

    def __post_init__(self) -> None:
        self.bound = {name: self.bindings[PARAMETER_VARIABLE_PREFIX + name] for name in self.source.parameters}
        if self.start is not None and "offset" in self.start:
            self.served_from = "query"
        self.chunks.append(self._read(self.start))

    def peek(self) -> TimelineEvent | None:
        if self._peeked is None and not self._done:
            self._peeked = self._nextevent_of()
            self._done = self._peeked is None
        return self._peeked[0] if self._peeked else None

    def take(self) -> TimelineEvent:
        event = self.peek()
        assert event is not None and self._peeked is not None
        self.at, self._peeked = self._peeked[1], None
        return event

    def position(self) -> Position:
        index, row = self.at
        chunk = self.chunks[index]
        if row == 0:
            return chunk.start
        if row == len(chunk.rows):
            return chunk.next
        if self.served_from == "query":
            return {"offset": int((chunk.start or {}).get("offset", 0)) + row}
        # The cursor of the last row taken: the page of exactly those rows ends there, if they are still the same.
        after = chunk.start["after"] if chunk.start else None
        again = self.source.kept.page(self.source.query.name, self.bound, row, 0, str(after) if after else None)
        if again is None or again.rows != chunk.rows[:row] or again.after is None:
            raise Moved(self.source.kind)
        return {"after": again.after}

    def _nextevent_of(self) -> tuple[TimelineEvent, tuple[int, int]] | None:
        index, row = self.at
        run: list[Row] = []
        key = self.source.key
        while True:
            chunk = self.chunks[index]
            while row < len(chunk.rows):
                current = chunk.rows[row]
                if run and (current.get(key), current.get("time")) != (run[0].get(key), run[0].get("time")):
                    return event_of(self.source.kind, key, run), (index, row)
                run.append(current)
                row += 1
            if chunk.last:
                return (event_of(self.source.kind, key, run), (index, row)) if run else None
            if index + 1 == len(self.chunks):
                self.chunks.append(self._read(chunk.next))
            if run:
                index, row = index + 1, 0
            else:  # nothing of this chunk is left: the next begins where the events not taken begin
                self.at = (index + 1, 0)
                index, row = self.at

    def _check_evaluable(self) -> None:
        """A filter the rows keep as facets (whether an activity involves a human) is an EXISTS in the query, which
        a store that skips the filters of a group opening with VALUES (Virtuoso 7: `wraps_values`) answers as
        false: there, such a window waits for the rows rather than miss its events."""
        facets = [name for name in self.source.parameters if name not in self.source.filters]
        given = [name for name in facets if self.bindings[PARAMETER_VARIABLE_PREFIX + name] is not None]
        if given and self.source.store.wraps_values:
            raise ViewNotReady(
                f"The timeline's {self.source.kind} events of one {given[0]} are being built; ask again in a moment."
            )

    def _read(self, start: Position) -> _Chunk:
        limit, self.chunk = self.chunk, min(self.chunk * 2, MAX_CHUNK)
        if self.served_from == "rows":
            after = str(start["after"]) if start else None
            page = self.source.kept.page(self.source.query.name, self.bound, limit, 0, after)
            if page is not None:
                return _Chunk(start, page.rows, {"after": page.after} if page.after else None, not page.has_more)
            if start is not None:
                raise Conflict(
                    f"The timeline's {self.source.kind} events are being rebuilt and cannot resume from a cursor "
                    "now; start again from the first page (without `after`)."
                )
            self.served_from = "query"  # being built: the query answers meanwhile
        self._check_evaluable()
        offset = int(start["offset"]) if start else 0
        result = evaluated_page(self.source.store, self.source.query.text, self.bindings, limit + 1, offset)
        rows = json_rows(result)
        more = len(rows) > limit
        return _Chunk(start, rows[:limit], {"offset": offset + limit} if more else None, not more)
