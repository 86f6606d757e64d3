"""One event of a timeline: its kind, the resource it is about, its time, the rows its query gave for it, and
the row the API answers with (its sentence and links); and the events of a kind's rows, as its query orders them."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from urllib.parse import quote

from segb_server.backend.services.timeline.kinds import RANK
from segb_server.backend.services.timeline.sentences import Rows, Told, tell
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.store.base import SelectResult

Row = dict[str, JsonValue]
COLUMNS = ["time", "kind", "sentence", "robot", "humans", "iri", "explain", "graph"]  # the CSV's, in order


@dataclass(frozen=True)
class TimelineEvent:
    kind: str
    key: str  # the IRI of what the event is about: a message, an activity, an emotion, a state, …
    time: str  # UTC, ISO 8601 with Z (as every answer writes times)
    rows: Rows  # the rows its query gave for it (several with several targets, models, properties, …)
    told: Told | None = None  # its sentence, when its source tells it itself (findings)
    tag: str = ""  # tells apart events of one kind, key and time (two rules' findings about one message)

    @property
    def order(self) -> tuple[tuple[int, str], int]:
        """Events in time order; at one instant, in the order of kinds (what an activity was before what it
        used and produced)."""
        return moment(self.time), RANK.get(self.kind, len(RANK))

    def row(self) -> dict[str, JsonValue | list[str]]:
        told = self.told or tell(self.kind, self.rows)
        quoted = quote(self.key, safe="")  # urlencode per link took most of a page's time (5,000 rows: 0.47 s)
        return {
            "id": f"{self.kind} {self.key} {self.time}" + (f" {self.tag}" if self.tag else ""),
            "time": self.time,
            "kind": self.kind,
            "sentence": told.sentence,
            "robot": told.robot,
            "humans": told.humans,
            "iri": self.key,
            "explain": "/explain?iri=" + quoted,
            "graph": "/kg-graph?focus=" + quoted,
        }


def moment(time: str) -> tuple[int, str]:
    """A time as it sorts: instants first (fixed-width UTC text), then anything that is no time, by its text
    (as a query's ORDER BY puts a literal of another type after date-times)."""
    try:
        parsed = datetime.fromisoformat(time.replace("Z", "+00:00"))
    except ValueError:
        return 1, time
    if parsed.tzinfo is None:
        return 1, time
    return 0, parsed.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%f")


def json_rows(result: SelectResult) -> list[Row]:
    return [{column: json_value(row.get(column)) for column in result.columns} for row in result.rows]


def grouped(kind: str, key: str, rows: list[Row]) -> list[TimelineEvent]:
    """The events of rows in their query's order: each run of rows with one key and one time is one event."""
    events: list[TimelineEvent] = []
    run: list[Row] = []
    for row in rows:
        if run and (row.get(key), row.get("time")) != (run[0].get(key), run[0].get("time")):
            events.append(event_of(kind, key, run))
            run = []
        run.append(row)
    if run:
        events.append(event_of(kind, key, run))
    return events


def event_of(kind: str, key: str, rows: list[Row]) -> TimelineEvent:
    return TimelineEvent(kind, str(rows[0].get(key)), str(rows[0].get("time")), tuple(rows))
