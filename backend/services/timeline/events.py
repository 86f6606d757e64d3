"""One event of a timeline: its kind, the resource it is about, its time, the rows its query gave for it, and
the row the API answers with (its sentence and links)."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from urllib.parse import quote

from segb_server.backend.services.timeline.kinds import RANK
from segb_server.backend.services.timeline.sentences import Rows, Told, tell
from segb_server.backend.services.values import JsonValue

COLUMNS = ["time", "kind", "sentence", "robot", "humans", "iri", "explain", "graph"]  # the CSV's, in order


@dataclass(frozen=True)
class TimelineEvent:
    kind: str
    key: str  # the IRI of what the event is about: a message, an activity, an emotion, a state, …
    time: str  # UTC, ISO 8601 with Z (as every answer writes times)
    rows: Rows  # the rows its query gave for it (several with several targets, models, properties, …)
    told: Told | None = None  # its sentence, when its source tells it itself (findings)

    @property
    def order(self) -> tuple[tuple[int, str], int]:
        """Events in time order; at one instant, in the order of kinds (what an activity was before what it
        used and produced)."""
        return moment(self.time), RANK.get(self.kind, len(RANK))

    def row(self) -> dict[str, JsonValue | list[str]]:
        told = self.told or tell(self.kind, self.rows)
        quoted = quote(self.key, safe="")  # urlencode per link took most of a page's time (5,000 rows: 0.47 s)
        return {
            "id": f"{self.kind} {self.key} {self.time}",
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
