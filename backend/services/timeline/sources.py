"""Where a timeline's events come from: one source per kind, read in time order from a position.

A timeline is the union of its sources, merged in time order (`service.py`). Each kind's query
(`sparql/timeline/<kind>.rq`) is a `KeptSource`: read from its kept rows (keyset: a position is the rows'
cursor), or, while they are being built, by evaluating the query (a position is an offset). Another source
joins by offering the same two methods (`reader`, `events_of`): the audit rules' findings become one more
source once their service exists (see docs/timeline.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Protocol

from pyoxigraph import NamedNode

from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, CatalogQuery
from segb_server.backend.services.timeline.events import Row, TimelineEvent, grouped, json_rows, moment
from segb_server.backend.services.views.kept_queries.plan import declared_key, plan_report
from segb_server.backend.services.views.kept_queries.projection import KeptQueries
from segb_server.backend.services.views.timeline_rows import MAX_CHUNK, KeptReader, Position
from segb_server.backend.store.base import Bindings, Store, select
from segb_server.backend.store.terms import bind_rows, bind_values

FIRST_CHUNK = 200  # rows read at once from a source at first; each further read doubles, up to MAX_CHUNK
KEYS_PER_QUERY = 300  # keys of the live stream's changes asked at once


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
