"""How far the views are: each view's lane through the journal, every view's (the least of them), how far each
is behind the store and how long its oldest missing entry has waited, what they miss, and waiting for them."""

from __future__ import annotations

import threading
from dataclasses import replace

from pyoxigraph import Quad

from segb_server.backend.services.views.lanes import ViewLane, ViewTime
from segb_server.backend.services.views.preparing import ViewBuilds
from segb_server.backend.services.views.view import KeptView
from segb_server.backend.services.writing.applier import applied_steps
from segb_server.backend.services.writing.cursor import Cursor
from segb_server.backend.services.writing.journal import Journal


class ViewsProgress:
    def __init__(self, journal: Journal, views: list[KeptView], lanes: dict[str, ViewLane], builds: ViewBuilds) -> None:
        self.journal = journal
        self.views = views
        self.lanes = lanes
        self.builds = builds
        self.cursor = Cursor()  # the journal entry every view is current through (the lanes' least)
        self._markers: list[tuple[int, threading.Event]] = []  # `wait_until_current`'s: (entry, done)
        self._markers_lock = threading.Lock()
        self.dispatched = 0  # the journal entry the batches handed to the lanes end at (the keeper's to move)

    def advanced(self) -> None:
        """A lane moved: the common cursor follows the least of the lanes not set aside (all of what was handed
        out when every view is), and the markers it reached fire."""
        kept = [lane.cursor.value for lane in self.lanes.values() if not self.builds.is_set_aside(lane.view)]
        self.cursor.advance(min(kept, default=self.dispatched))
        with self._markers_lock:
            reached = [done for at, done in self._markers if at <= self.cursor.value]
            self._markers = [(at, done) for at, done in self._markers if at > self.cursor.value]
        for done in reached:
            done.set()

    def fire_at(self, through: int, markers: list[threading.Event]) -> None:
        """Set each of `markers` once every view is through entry `through`."""
        with self._markers_lock:
            self._markers += [(through, done) for done in markers]
        self.advanced()

    def wait_for(self, sequence: int, timeout: float) -> bool:
        """Wait until the views include journal entry `sequence` (True), or `timeout` seconds passed."""
        return self.cursor.wait_for(sequence, timeout, reached=self._served_from_views)

    def _served_from_views(self) -> bool:
        """Every view is ready, but those set aside (tried again later; their reports are evaluated in full)."""
        return all(view.ready or self.builds.is_set_aside(view) for view in self.views)

    def view_times(self) -> dict[str, ViewTime]:
        """Each view's updates so far (a copy)."""
        return {name: replace(lane.spent) for name, lane in self.lanes.items()}

    @property
    def through(self) -> int:
        """The journal entry every view is current through."""
        return self.cursor.value

    def view_through(self, name: str) -> int:
        """The journal entry view `name` is current through."""
        return self.lanes[name].cursor.value

    def lag(self, applied: int, view: str | None = None) -> tuple[int, float]:
        """Journal entries the store has and the views (or `view`) do not have yet, and how long the oldest of
        them has waited (seconds); nothing before the views are first ready: until then they are not what
        answers."""
        through = self.through if view is None else self.view_through(view)
        behind = self._behind(applied, through)
        return behind, self.journal.age_of(through + 1) if behind else 0.0

    def view_lags(self, applied: int) -> dict[str, tuple[int, float]]:
        """Each view behind the store: how many entries, and how long the oldest it misses has waited."""
        lags = {name: self.lag(applied, name) for name, lane in self.lanes.items() if applied > lane.cursor.value}
        return {name: lag for name, lag in lags.items() if lag[0]}

    def building(self, applied: int) -> list[str]:
        """The views not ready yet (built at start, or rebuilt) while the store holds entries they do not:
        what reads them answers from the store meanwhile, or (the findings) says it is building. None when
        there is nothing they miss (an empty store: nothing to build)."""
        if applied <= self.through and not self.builds.any_set_aside:
            return []
        return [view.name for view in self.views if not view.ready]

    def behind(self, applied: int) -> int:
        """Journal entries the store has through `applied` and the views do not (0 before they are ready)."""
        return self._behind(applied, self.through)

    def _behind(self, applied: int, through: int) -> int:
        if not any(view.ready for view in self.views):
            return 0
        return max(0, applied - through)

    def pending(self, applied: int, limit: int, view: str | None = None) -> list[Quad] | None:
        """The triples the store has through entry `applied` and the views (or `view`) do not have yet, read from
        the journal (a reader adds them to what a view holds to answer as the store would); None when they
        cannot stand in for the store: a clearing is among those entries, or more than `limit` of them."""
        behind = self._behind(applied, self.through if view is None else self.view_through(view))
        if behind == 0:
            return []
        if behind > limit:
            return None
        steps = applied_steps(self.journal.entries_after(applied - behind, behind))
        if any(step.cleared or step.erased for step in steps):
            return None
        return [quad for step in steps for quad in step.quads]
