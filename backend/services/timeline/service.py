"""The timeline of one robot or one human over a window: every kind's events merged in time order, a page at a
time.

Each kind's source is read from its position in the page's cursor, a chunk of rows at a time, and the sources'
next events are merged (a heap of one event per source) until the page is full. The next page's cursor holds
every source's position after what this page took, so a page costs its own events and a chunk per kind,
however deep in the window it is and however long the log.
"""

from __future__ import annotations

import base64
import binascii
import csv
import hashlib
import heapq
import io
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from segb_server.backend.services.csv_cells import spreadsheet_safe
from segb_server.backend.services.errors import Conflict, InvalidParameter
from segb_server.backend.services.sparql.catalog import Parameter, check_window, to_term
from segb_server.backend.services.timeline.events import COLUMNS, TimelineEvent
from segb_server.backend.services.timeline.kinds import KINDS
from segb_server.backend.services.timeline.sources import FIRST_CHUNK, Reader, Source, Window
from segb_server.backend.services.values import JsonValue
from segb_server.backend.services.views.timeline_rows import Moved, Position

DEFAULT_LIMIT = 1000
MAX_LIMIT = 10_000
MAX_DOCUMENT_ROWS = 100_000  # events a timeline written as one HTML file holds at most
END = "end"  # a source's position once it has nothing left in the window
READS_PER_PAGE = 3  # a page read again when a source's rows changed under it, at most this many times
CURSOR_VERSION = 1


@dataclass(frozen=True)
class TimelinePage:
    window: Window
    kinds: list[str]
    rows: list[dict[str, JsonValue | list[str]]]
    limit: int
    has_more: bool
    next: str | None
    served_from: dict[str, str]  # kind → "rows" (kept current) or "query" (evaluated while rows are built)
    last_event_id: int | None  # where `GET /timeline/stream` resumes to hear of every later change

    def as_json(self) -> dict[str, object]:
        window = self.window
        return {
            "robot": window.robot,
            "human": window.human,
            "since": window.since,
            "until": window.until,
            "kinds": self.kinds,
            "columns": COLUMNS,
            "rows": self.rows,
            "limit": self.limit,
            "has_more": self.has_more,
            "next": self.next,
            "served_from": self.served_from,
            "last_event_id": self.last_event_id,
        }

    def as_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\r\n")
        writer.writerow(COLUMNS)
        for row in self.rows:
            writer.writerow([_cell(row.get(column)) for column in COLUMNS])
        return buffer.getvalue()


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, list):
        return spreadsheet_safe(" ".join(str(item) for item in value))
    return spreadsheet_safe(str(value))


class TimelineService:
    def __init__(self, sources: Sequence[Source], last_change: Callable[[], int] | None = None) -> None:
        self.sources = {source.kind: source for source in sources}
        self.last_change = last_change  # the position of the live stream the kept rows include

    @property
    def kinds(self) -> list[str]:
        return [kind for kind in KINDS if kind in self.sources]

    def window(self, values: Mapping[str, str | None]) -> Window:
        """The filters of a request, checked: robot or human (one is needed), since and until."""
        window = Window(**{name: (values.get(name) or None) for name in ("robot", "human", "since", "until")})
        if window.robot is None and window.human is None:
            raise InvalidParameter("robot", "a timeline is of one robot or one human: give `robot` or `human`")
        for name, kind in (("robot", "iri"), ("human", "iri"), ("since", "dateTime"), ("until", "dateTime")):
            raw = getattr(window, name)
            if raw is not None:
                to_term(Parameter(name, kind), raw)  # type: ignore[arg-type]  # 422 naming a bad value
        check_window(window.since, window.until)
        return window

    def chosen_kinds(self, asked: Sequence[str]) -> list[str]:
        wanted = [kind for part in asked for kind in part.split(",") if kind]
        unknown = [kind for kind in wanted if kind not in self.sources]
        if unknown:
            raise InvalidParameter("kind", f"'{unknown[0]}' is no kind of event; kinds: {', '.join(self.kinds)}")
        return [kind for kind in self.kinds if kind in wanted] if wanted else self.kinds

    def page(self, window: Window, kinds: list[str], limit: int, after: str | None = None) -> TimelinePage:
        """`limit` events of the window in time order, after the cursor `after`; blocking (SQLite or store
        I/O), so call it off the event loop."""
        fingerprint = _fingerprint(window, kinds)
        positions = _decoded(after, fingerprint, kinds) if after else {}
        # Read before the rows: a change committed meanwhile is announced again to a reader resuming from here.
        last_event_id = self.last_change() if self.last_change else None
        sources = [self.sources[kind] for kind in kinds if self._shows(self.sources[kind], window)]
        for _ in range(READS_PER_PAGE):
            try:
                return self._merged(window, kinds, sources, positions, limit, fingerprint, last_event_id)
            except Moved:
                continue
        raise Conflict("The timeline changed while this page was read; ask for it again.")

    def whole(
        self, window: Window, kinds: list[str], most: int = MAX_DOCUMENT_ROWS
    ) -> tuple[list[dict[str, JsonValue | list[str]]], bool]:
        """The window's first `most` events, and whether it holds more; blocking."""
        rows: list[dict[str, JsonValue | list[str]]] = []
        after: str | None = None
        while True:
            page = self.page(window, kinds, min(MAX_LIMIT, most - len(rows)), after)
            rows += page.rows
            if not page.has_more or len(rows) >= most:
                return rows, page.has_more
            after = page.next

    def changed(self, kind: str, window: Window, keys: list[str]) -> list[dict[str, JsonValue | list[str]]]:
        """The rows of the `kind` events about `keys` (IRIs) in the window as they are now: what the live stream
        sends for the keys a change names. Blocking (store I/O)."""
        source = self.sources[kind]
        if not self._shows(source, window):
            return []
        return [event.row() for event in source.events_of(window, keys)]

    def _shows(self, source: Source, window: Window) -> bool:
        """A source shows in a window when it knows every filter given (states are of no human)."""
        return window.given() <= set(source.parameters)

    def _merged(
        self,
        window: Window,
        kinds: list[str],
        sources: list[Source],
        positions: dict[str, Position | str],
        limit: int,
        fingerprint: str,
        last_event_id: int | None,
    ) -> TimelinePage:
        chunk = min(limit + 1, FIRST_CHUNK)
        readers: dict[str, Reader] = {}
        for source in sources:
            position = positions.get(source.kind)
            if position != END:
                readers[source.kind] = source.reader(window, position, chunk)  # type: ignore[arg-type]
        heap: list[tuple[object, str]] = []
        for kind, reader in readers.items():
            if (event := reader.peek()) is not None:
                heap.append((event.order, kind))
        heapq.heapify(heap)
        taken: list[TimelineEvent] = []
        while heap and len(taken) < limit:
            _, kind = heapq.heappop(heap)
            taken.append(readers[kind].take())
            if (event := readers[kind].peek()) is not None:
                heapq.heappush(heap, (event.order, kind))
        has_more = bool(heap)
        following: dict[str, Position | str] = {source.kind: END for source in sources}
        for kind, reader in readers.items():
            if reader.peek() is not None:
                following[kind] = reader.position()
        cursor = _encoded(fingerprint, following) if has_more else None
        return TimelinePage(
            window=window,
            kinds=kinds,
            rows=[event.row() for event in taken],
            limit=limit,
            has_more=has_more,
            next=cursor,
            served_from={kind: reader.served_from for kind, reader in readers.items()},
            last_event_id=last_event_id,
        )


def _fingerprint(window: Window, kinds: list[str]) -> str:
    """What a cursor was made for: it is refused for other filters (its positions would mean other rows)."""
    asked = json.dumps([window.robot, window.human, window.since, window.until, kinds])
    return hashlib.sha256(asked.encode()).hexdigest()[:16]


def _encoded(fingerprint: str, positions: dict[str, Position | str]) -> str:
    """Opaque and URL-safe: clients pass it back as it is."""
    text = json.dumps({"v": CURSOR_VERSION, "f": fingerprint, "p": positions}, separators=(",", ":"))
    return base64.urlsafe_b64encode(text.encode()).decode("ascii").rstrip("=")


def _decoded(after: str, fingerprint: str, kinds: list[str]) -> dict[str, Position | str]:
    """The positions a `next` cursor names. Cursors come back from clients: anything but one this server made
    for these filters is refused by name."""
    try:
        decoded = json.loads(base64.urlsafe_b64decode(after.encode("ascii") + b"=" * (-len(after) % 4)))
    except (ValueError, UnicodeError, binascii.Error):
        decoded = None
    if not (isinstance(decoded, dict) and decoded.get("v") == CURSOR_VERSION and isinstance(decoded.get("p"), dict)):
        raise InvalidParameter("after", "not a cursor this server made: pass the `next` of the previous page")
    if decoded.get("f") != fingerprint:
        raise InvalidParameter("after", "made for other filters or kinds: pass the `next` of a page with these")
    positions: dict[str, Position | str] = {}
    for kind, position in decoded["p"].items():
        if kind not in kinds or not _valid_position(position):
            raise InvalidParameter("after", "not a cursor this server made: pass the `next` of the previous page")
        positions[kind] = position
    return positions


def _valid_position(position: object) -> bool:
    if position is None or position == END:
        return True
    if not isinstance(position, dict) or len(position) != 1:
        return False
    ((name, value),) = position.items()
    if name == "after":
        return isinstance(value, str)
    return name == "offset" and isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 2**62
