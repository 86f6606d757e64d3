"""Where a timeline's events come from: one source per kind, read in time order from a position.

A timeline is the union of its sources, merged in time order (`service.py`). Each kind's query
(`sparql/timeline/<kind>.rq`) is a `KeptSource`: read from its kept rows (keyset: a position is the rows'
cursor), or, while they are being built, by evaluating the query (a position is an offset). Another source
joins by offering the same two methods (`reader`, `events_of`): the audit rules' findings become one more
source once their service exists (see docs/timeline.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Protocol

from pyoxigraph import NamedNode

from segb_server.backend.services.errors import Conflict, ViewNotReady
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.sparql.paging import evaluated_page
from segb_server.backend.services.timeline.events import TimelineEvent, moment
from segb_server.backend.services.upkeep.kept_queries.plan import declared_key, plan_report
from segb_server.backend.services.upkeep.kept_queries.projection import KeptQueries
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.store.base import Bindings, SelectResult, Store, select
from segb_server.backend.store.terms import bind_rows, bind_values

# A position in a source: {"after": cursor} in its kept rows, {"offset": n} in its query's answer, None for its
# first event.
Position = dict[str, str | int] | None
Row = dict[str, JsonValue]

FIRST_CHUNK = 200  # rows read at once from a source at first; each further read doubles, up to MAX_CHUNK
MAX_CHUNK = 5_000
KEYS_PER_QUERY = 300  # keys of the live stream's changes asked at once


class Moved(Exception):
    """A source's rows changed between two reads of one page: the page is read again."""


@dataclass(frozen=True)
class Window:
    """What a timeline is asked for: its filters, as the query string gave them (checked by each query)."""

    robot: str | None = None
    human: str | None = None
    since: str | None = None
    until: str | None = None

    def values(self, parameters: Mapping[str, object]) -> dict[str, str | None]:
        given = {"robot": self.robot, "human": self.human, "since": self.since, "until": self.until}
        return {name: value for name, value in given.items() if name in parameters}

    def holds(self, time: str) -> bool:
        """Whether `time` is in the window (both ends included)."""
        instant = moment(time)
        return not (self.since and instant < moment(self.since)) and not (self.until and instant > moment(self.until))

    def given(self) -> set[str]:
        return {name for name in ("robot", "human", "since", "until") if getattr(self, name) is not None}


class Reader(Protocol):
    served_from: str  # "rows" or "query"

    def peek(self) -> TimelineEvent | None:
        """The next event, not taken yet; None when the source has no more."""

    def take(self) -> TimelineEvent:
        """The next event, taken."""

    def position(self) -> Position:
        """Where the events after those taken start. Raises `Moved` when that cannot be told exactly."""


class Source(Protocol):
    kind: str

    @property
    def parameters(self) -> Mapping[str, object]:
        """The filters it knows (robot, human, since, until); a timeline filtered by another leaves it out."""

    def reader(self, window: Window, position: Position, chunk: int) -> Reader:
        """Its events in `window` from `position` on, read `chunk` rows (or so) at a time."""

    def events_of(self, window: Window, keys: list[str]) -> list[TimelineEvent]:
        """The events about `keys` (IRIs) in `window`, as they are now (for the live stream)."""


class KeptSource:
    """One kind's query, kept as rows by `kept` (the timeline's `KeptQueries`)."""

    def __init__(self, kind: str, query: CatalogQuery, kept: KeptQueries, store: Store) -> None:
        self.kind = kind
        self.query = query
        self.kept = kept
        self.store = store
        self.parameters = query.parameters
        self.key = declared_key(query)[0][1:]  # the variable its rows are kept by, e.g. `message`
        # Each parameter's column and comparison (`FILTER (!BOUND(?param_x) || ?column <op> ?param_x)`).
        self.filters = {f.parameter: (f.column[1:], f.op) for f in plan_report(query).column_filters}

    def bindings(self, window: Window) -> Bindings:
        return self.query.bindings(window.values(self.parameters))

    def reader(self, window: Window, position: Position, chunk: int) -> KeptReader:
        return KeptReader(self, self.bindings(window), position, chunk)

    def events_of(self, window: Window, keys: list[str]) -> list[TimelineEvent]:
        """The keys' events as they are now, held to the window as a page holds them: their rows read from the
        store as the rows are kept (every parameter unbound, the keys bound), then, at each of their times, the
        window's page of the kept rows keeps those it holds (whether an activity involves a human is a join the
        rows alone do not tell; the page knows it)."""
        text = bind_values(self.query.text, {PARAMETER_VARIABLE_PREFIX + name: None for name in self.parameters})
        current: list[TimelineEvent] = []
        for start in range(0, len(keys), KEYS_PER_QUERY):
            chunk = [[NamedNode(key)] for key in keys[start : start + KEYS_PER_QUERY]]
            bound = bind_rows(text, [self.key], chunk, wrap=self.store.wraps_values)  # type: ignore[arg-type]
            current += grouped(self.kind, self.key, json_rows(select(self.store, bound)))
        wanted = set(keys)
        events: list[TimelineEvent] = []
        for time in sorted({event.time for event in current if window.holds(event.time)}, key=moment):
            held = self._held(window, time, wanted)
            events += held if held is not None else [e for e in current if e.time == time and self._admits(window, e)]
        return events

    def _held(self, window: Window, time: str, keys: set[str]) -> list[TimelineEvent] | None:
        """The events about `keys` at `time` that the window's page of the kept rows holds; None while the rows
        are not kept."""
        if (window.since and moment(time) < moment(window.since)) or (
            window.until and moment(time) > moment(window.until)
        ):
            return []
        at = replace(window, since=time, until=time)
        bindings = self.bindings(at)
        bound = {name: bindings[PARAMETER_VARIABLE_PREFIX + name] for name in self.parameters}
        rows: list[Row] = []
        after: str | None = None
        while True:
            page = self.kept.page(self.query.name, bound, MAX_CHUNK, 0, after)
            if page is None:
                return None
            rows += [row for row in page.rows if str(row.get(self.key)) in keys]
            if not page.has_more:
                return grouped(self.kind, self.key, rows)
            after = page.after

    def _admits(self, window: Window, event: TimelineEvent) -> bool:
        """While the rows are being built: the window's column filters, compared here; a filter the rows do not
        hold as a column (a facet) admits nothing, rather than an event the window may not hold."""
        for parameter, value in window.values(self.parameters).items():
            if value is None:
                continue
            if parameter not in self.filters:
                return False
            column, op = self.filters[parameter]
            if op == "=" and value not in [row.get(column) for row in event.rows]:
                return False  # (a time's window is held by the caller)
        return True


def json_rows(result: SelectResult) -> list[Row]:
    return [{column: json_value(row.get(column)) for column in result.columns} for row in result.rows]


def grouped(kind: str, key: str, rows: list[Row]) -> list[TimelineEvent]:
    """The events of rows in their query's order: each run of rows with one key and one time is one event."""
    events: list[TimelineEvent] = []
    run: list[Row] = []
    for row in rows:
        if run and (row.get(key), row.get("time")) != (run[0].get(key), run[0].get("time")):
            events.append(_event(kind, key, run))
            run = []
        run.append(row)
    if run:
        events.append(_event(kind, key, run))
    return events


def _event(kind: str, key: str, rows: list[Row]) -> TimelineEvent:
    return TimelineEvent(kind, str(rows[0].get(key)), str(rows[0].get("time")), tuple(rows))


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
            self._peeked = self._next_event()
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

    def _next_event(self) -> tuple[TimelineEvent, tuple[int, int]] | None:
        index, row = self.at
        run: list[Row] = []
        key = self.source.key
        while True:
            chunk = self.chunks[index]
            while row < len(chunk.rows):
                current = chunk.rows[row]
                if run and (current.get(key), current.get("time")) != (run[0].get(key), run[0].get("time")):
                    return _event(self.source.kind, key, run), (index, row)
                run.append(current)
                row += 1
            if chunk.last:
                return (_event(self.source.kind, key, run), (index, row)) if run else None
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
