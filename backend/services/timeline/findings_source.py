"""The audit rules' findings as one more source of a timeline: each finding with a time is an event of kind
`finding` about its focus node, told by its rule (severity, title, the rule's own message).

Read through the findings service, in its time order and with its cursors, so the timeline shows exactly what
`GET /findings` lists for the same robot, human and window. A finding without a time (a shape's focus node that
has none) has no place on a timeline: it is left out here and stays on the findings page.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from segb_server.backend.services.rules.findings import Finding
from segb_server.backend.services.rules.service import FILTERS, FindingsService, Selection
from segb_server.backend.services.timeline.events import TimelineEvent, moment
from segb_server.backend.services.timeline.kinds import FINDING
from segb_server.backend.services.timeline.sentences import Told
from segb_server.backend.services.timeline.sources import Window
from segb_server.backend.services.views.timeline_rows import Position

SEVERITY_WORDS = {"violation": "Violation", "warning": "Warning", "info": "Note"}


def told(found: Finding) -> Told:
    """`Warning: Message answered late — ARI answered Maria after 14 s` (the rule's title, then its message)."""
    severity = SEVERITY_WORDS.get(str(found["severity"]), str(found["severity"]).capitalize())
    message = found.get("message")
    sentence = f"{severity}: {found['title']}" + (f" — {' '.join(str(message).split())}" if message else "")
    robot = found.get("robot")
    human = found.get("human")
    return Told(sentence, str(robot) if robot else None, [str(human)] if human else [])


def event(found: Finding) -> TimelineEvent:
    rule = str(found["rule"])
    return TimelineEvent(FINDING, str(found["focus"]), str(found["time"]), ({"rule": rule},), told(found), rule)


def _timed(found: Finding) -> bool:
    return bool(found.get("time")) and moment(str(found["time"]))[0] == 0


class FindingSource:
    kind = FINDING

    def __init__(self, findings: FindingsService) -> None:
        self.findings = findings

    @property
    def parameters(self) -> Mapping[str, object]:
        return dict.fromkeys(FILTERS)

    def selection(self, window: Window) -> Selection:
        given = {name: value for name, value in window.values(self.parameters).items() if value is not None}
        return self.findings.selection({name: [value] for name, value in given.items()})

    def reader(self, window: Window, position: Position, chunk: int) -> FindingReader:
        return FindingReader(self, self.selection(window), position, chunk)

    def events_of(self, window: Window, keys: list[str]) -> list[TimelineEvent]:
        """The findings about `keys` in the window, as they are now (for the live stream)."""
        selection = self.selection(window)
        taken = {rule.id for rule in selection.rules if selection.takes(rule)}
        events = []
        for found in self.findings.about(keys):
            if found["rule"] not in taken or not _timed(found) or not window.holds(str(found["time"])):
                continue
            if window.robot and found.get("robot") != window.robot:
                continue
            if window.human and found.get("human") != window.human:
                continue
            events.append(event(found))
        return events


@dataclass
class FindingReader:
    """The findings from a position (the findings service's cursor), a page of `chunk` at a time."""

    source: FindingSource
    selection: Selection
    start: Position
    chunk: int
    served_from: str = "rows"
    _page: list[Finding] = field(default_factory=list)
    _page_start: str | None = None  # the cursor the current page was read from
    _next: str | None = None  # the cursor after the current page; None when it is the last
    _taken: int = 0  # of the current page, timed or not

    def __post_init__(self) -> None:
        self._read(str(self.start["after"]) if self.start else None)

    def _read(self, after: str | None) -> None:
        page = self.source.findings.page(self.selection, self.chunk, after)
        self._page, self._page_start, self._taken = page.findings, after, 0
        self._next = page.next if page.has_more else None
        if "building" in page.served_from.values():
            self.served_from = "building"

    def peek(self) -> TimelineEvent | None:
        while True:
            while self._taken < len(self._page):
                if _timed(self._page[self._taken]):
                    return event(self._page[self._taken])
                self._taken += 1  # no time: not on a timeline
            if self._next is None:
                return None
            self._read(self._next)

    def take(self) -> TimelineEvent:
        found = self.peek()
        assert found is not None
        self._taken += 1
        return found

    def position(self) -> Position:
        if self._taken == 0:
            return {"after": self._page_start} if self._page_start else None
        if self._taken == len(self._page) and self._next is not None:
            return {"after": self._next}
        # Inside a page: the cursor after exactly the findings taken of it.
        again = self.source.findings.page(self.selection, self._taken, self._page_start)
        return {"after": again.next} if again.next else None
