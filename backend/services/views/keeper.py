"""Keeping views current from the journal's stream of new triples.

A view (a report's rows, the graph index) is a `KeptView` (`view.py`): built once from the whole store, then
updated from what each applied journal step added, and emptied by a clearing. The `ViewKeeper` takes the steps
the applier hands it in batches and gives each batch to every view's lane (`lanes.py`): each view follows the
same stream in the same order, at its own pace. A view records the journal sequence it includes: after a restart
it catches up from the journal instead of being built again (`preparing.py`). Before a batch reaches the views,
the registry of the IRIs the store holds (`seen_terms.py`) takes it, and tells them which of the batch's IRIs are
fresh: joins from those are followed among the batch's triples.

On a remote store the views of one batch are updated side by side: their work is mostly waiting for the store's
answers (a round trip per query), so a batch takes as long as its slowest view rather than all of them added up.
On the embedded store the same work is this process's own CPU, which the posts need too: two views go side by
side there, and a third for small batches (`lanes.Turns`). The store works out an answer without holding the
interpreter (`store/solutions.py`), so one view's query runs on one core while another view's Python runs on the
other; a single thread left a core idle while the views fell behind (a soak of one robot: the views 22 s behind
after a minute, 1.3 s with two).

With several API processes on one data directory, only the one holding the data directory's leadership keeps
the views; the others follow the views it stores, which they read to answer. When the leader goes, the
process that takes over catches the views up from the journal and keeps them. The views' keeper is usually
the applier too, and gets its steps as they are applied; on a host whose processes do not apply (the state is
in PostgreSQL and another host's process applies), it reads them from the journal as the store's cursor
advances.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.ops.leadership import Lead, Leadership
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.lane_hosting import LaneHosting
from segb_server.backend.services.views.lanes import SMALL_BATCH_TRIPLES, Batch, ViewLane, ViewTime
from segb_server.backend.services.views.preparing import ViewBuilds
from segb_server.backend.services.views.progress import ViewsProgress
from segb_server.backend.services.views.seen_terms import SeenTerms
from segb_server.backend.services.views.steps import MAX_QUEUED_TRIPLES, Marker, StepQueue, Unread
from segb_server.backend.services.views.turns import Turns
from segb_server.backend.services.views.view import ForgetsErased, KeptView
from segb_server.backend.services.writing.applier import Applied, Applier
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.store.base import Store

logger = logging.getLogger("segb.views")

# After a batch, the keeper rests this many times as long as the batch took before taking the next: under a
# steady stream of posts the views then use at most half of the time (and of the store's), the next batch
# holds more posts for the same number of queries, and requests keep their share of the cores. Never longer
# than MAX_REST_SECONDS: after a slow batch a long rest would let the next one grow, and the views fall behind.
REST_RATIO = 1.0
MAX_REST_SECONDS = 0.25
# Nor does the keeper rest while the views are this far behind (the oldest step waiting, seconds): under more
# posts than the views keep up with at half the time, they take the time they need, and the posts slow down
# rather than the views falling behind without end.
NO_REST_BEHIND_SECONDS = 1.0
# The keeper waits for every view to take a small batch before it hands out the next (they then share one batch's
# answers from the store), but no longer than this once one view is through with it: a view slow on it is let go,
# and the others take the next posts meanwhile (`lanes.py`). After a large batch it does not wait at all: the
# next posts go ahead of it in the views that let them.
HOLD_SECONDS = 0.5
EMBEDDED_VIEW_TURNS = 2  # views updated side by side on the embedded store (see the module's docstring)
FOLLOW_SECONDS = 0.25  # how often a following process reads how far the leader's views are
# The batches the lanes hold are bounded too: past this many triples, a batch reaches the lanes behind without its
# triples, which such a lane reads back from the journal at its turn (the queue's bound is `steps.py`'s).
LANES_MAX_HELD_TRIPLES = 200_000

__all__ = ["MAX_REST_SECONDS", "REST_RATIO", "ForgetsErased", "KeptView", "ViewKeeper", "ViewTime"]


class ViewKeeper:
    def __init__(
        self,
        store: Store,
        journal: Journal,
        views: list[KeptView],
        leadership: Lead | None = None,
        applier: Applier | None = None,
        housekeeping: Callable[[], None] | None = None,
        max_queued_triples: int = MAX_QUEUED_TRIPLES,
        seen_terms: SeenTerms | None = None,
        rest_ratio: float = REST_RATIO,
    ) -> None:
        """`applier`: the process's applier, when the views' leadership is not its (then, while it does not
        apply, the views read what it saw applied from the journal). `housekeeping`: run once the views are
        ready, by the process that keeps them (the only one that writes them). `seen_terms`: the IRIs the store
        has held, kept here a step ahead of the views, which it tells which of a batch's terms are fresh."""
        self.store = store
        self.journal = journal
        self.views = views
        self.seen_terms = seen_terms
        self.leadership = leadership or Leadership(None)
        applier = applier if applier is not None and applier.leadership is not self.leadership else None
        self.rest_ratio = rest_ratio
        self._housekeeping = housekeeping
        self._thread: threading.Thread | None = None
        self.stopping = threading.Event()  # ends retry waits too: a store that never returns must not hold shutdown
        self.steps = StepQueue(journal, applier, self.stopping, max_queued_triples)
        self.on_applied = self.steps.on_applied  # the applier's listener
        self.wait_until_current = self.steps.wait_until_current
        self._outage: str | None = None  # the error of the store or state the keeper's thread retries
        # Every view is being built from the store (at start, or again after an erasure): their lag is that build's,
        # not posts outpacing their upkeep. Written by the keeper's thread, read by requests.
        self.building_all = False
        self.builds = ViewBuilds(store, journal, seen_terms)
        turns = max(1, len(views)) if store.remote else EMBEDDED_VIEW_TURNS
        self.lanes: dict[str, ViewLane] = {}
        self.progress = ViewsProgress(journal, views, self.lanes, self.builds)
        host = LaneHosting(journal, self.builds, self.progress, Turns(general=turns, express=1), self.stopping)
        self.lanes.update({view.name: ViewLane(view, host) for view in views})

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="segb-views", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self.stopping.set()
        self.steps.stop()
        if self._thread is not None:
            self._thread.join(timeout=30)
        for lane in self.lanes.values():
            lane.wake()
        for lane in self.lanes.values():
            lane.join(timeout=30)
        if self.seen_terms is not None:
            self.seen_terms.close()

    @property
    def outage(self) -> str | None:
        """The error of the store or state being retried, by the keeper's thread or a view's lane."""
        lanes = (lane.outage for lane in self.lanes.values() if lane.outage)
        return self._outage or self.steps.outage or next(lanes, None)

    @property
    def most_queued_triples(self) -> int:
        """The most triples the queue of applied steps has held (what its memory is bounded by)."""
        return self.steps.most_queued_triples

    @property
    def last_error(self) -> str | None:
        """What readiness tells as the views' error: the outage retried, else why the views set aside are not
        built (None when neither)."""
        return self.outage or self.builds.errors()

    # --- the keeper's thread --------------------------------------------------------------------------

    def lane_advanced(self) -> None:
        self.progress.advanced()

    def _run(self) -> None:
        while not self.leadership.try_acquire():
            self._follow()
            if self.stopping.wait(FOLLOW_SECONDS):
                return
        while True:
            try:
                self.building_all = True
                self._prepare_all()
                self._outage = None
                break
            except OUTAGES as error:
                self._outage = str(error)
                logger.warning("building the views failed (%s); retrying", error)
            finally:
                self.building_all = False
            if self.stopping.wait(2):
                return
        if self._housekeeping is not None:
            try:
                self._housekeeping()
            except Exception:  # leftovers stay for the next start; the views are kept current meanwhile
                logger.exception("tidying the views' storage failed")
        for lane in self.lanes.values():
            lane.start()
        rested = 0.0  # when the rest after the last batch ends (time.monotonic())
        while True:
            steps = self.steps.next_steps(rested, self.progress.dispatched)
            if steps is None:
                return
            applied = [step for step in steps if not isinstance(step, Marker)]
            began = time.monotonic()
            if applied and not self._process_retrying(applied):
                return
            self._mark([step for step in steps if isinstance(step, Marker)])
            ended = time.monotonic()
            resting = (
                applied and self.rest_ratio > 0 and self.steps.waited(self.progress.dispatched) < NO_REST_BEHIND_SECONDS
            )
            rested = ended + min(MAX_REST_SECONDS, self.rest_ratio * (ended - began)) if resting else 0.0

    def _mark(self, markers: list[Marker]) -> None:
        """Each marker fires once every view is through what was handed out before it."""
        self.progress.fire_at(self.progress.dispatched, [marker.done for marker in markers])

    def _process_retrying(self, applied: list[Applied | Unread]) -> bool:
        """Hand `applied` to the views, retrying while the store is away; False when stopped meanwhile."""
        while True:
            try:
                self._process(applied)
                return True
            except OUTAGES as error:
                self._outage = str(error)
                logger.warning("keeping the views current failed (%s); retrying", error)
                if self.stopping.wait(1):
                    return False
            except Exception:
                logger.exception("keeping the views current failed; building them again")
                last = applied[-1]
                through = last.last if isinstance(last, Unread) else last.entries[-1].sequence
                try:
                    self._build_all(through)
                except OUTAGES as outage:  # the thread lives on: the batch is tried again
                    self._outage = str(outage)
                    logger.warning("building the views again failed (%s); retrying", outage)
                    if self.stopping.wait(1):
                        return False
                    continue
                self._outage = None
                return True

    def _follow(self) -> None:
        try:
            stored = [view.follow() for view in self.views]
        except Exception as error:  # e.g. the leader is building a view of another version just now
            self._outage = str(error)
            return
        self._outage = None
        for view, through in zip(self.views, stored, strict=True):
            view.ready = through is not None
            if through is not None:
                self.lanes[view.name].cursor.advance(through)
        known = [through for through in stored if through is not None]
        if len(known) == len(stored):
            self.progress.cursor.advance(min(known))

    def _prepare_all(self) -> None:
        current = self.builds.prepare_all(self.views, self._view_prepared)
        self.progress.dispatched = max(self.progress.dispatched, current)
        self.lane_advanced()

    def _view_prepared(self, view: KeptView, through: int) -> None:
        self.lanes[view.name].cursor.advance(through)

    def _process(self, items: list[Applied | Unread]) -> None:
        if not self.views:  # KEEP_VIEWS=false: nothing to read or match; waiting for the views waits for the store
            last = items[-1]
            self.progress.dispatched = last.last if isinstance(last, Unread) else last.entries[-1].sequence
            self.lane_advanced()
            return
        steps = [step for step in self.steps.read_unread(items) if step.entries[-1].sequence > self.progress.dispatched]
        if not steps:
            return
        first = steps[0].entries[0].sequence
        if first > self.progress.dispatched + 1:  # applied by another process before this one took over: read them back
            steps = [*self.steps.read_back(self.progress.dispatched, first), *steps]
        cleared = max((index for index, step in enumerate(steps) if step.cleared or step.erased), default=-1)
        if cleared >= 0:
            self._clear_or_rebuild(steps[cleared])
            steps = [step for step in steps[cleared + 1 :] if step.entries[-1].sequence > self.progress.dispatched]
        if steps:
            self._hand_out(steps)

    def _clear_or_rebuild(self, step: Applied) -> None:
        """Once every lane is idle: after a clearing every view is emptied; after an erasure (triples went) every
        view is made again from the store."""
        self._wait_lanes_idle()
        at = step.entries[-1].sequence
        if step.erased:
            self.building_all = True
            try:
                at = self._rebuild_all(at)
            finally:
                self.building_all = False
        else:
            for view in self.views:
                view.clear(at)
            if self.seen_terms is not None:
                self.seen_terms.clear(at)
            for lane in self.lanes.values():
                lane.cursor.advance(at)
        self.progress.dispatched = max(self.progress.dispatched, at)
        self.lane_advanced()

    def _hand_out(self, steps: list[Applied]) -> None:
        """One batch of `steps` to every lane not set aside; then wait for the lanes in step to take it, at most
        HOLD_SECONDS past the first one through with it."""
        through = steps[-1].entries[-1].sequence
        quads = [quad for step in steps for quad in step.quads]
        fresh = frozenset[str]()
        if self.seen_terms is not None:  # registered before any view reads the batch
            fresh = self.seen_terms.admit(quads, steps[0].entries[0].sequence, through)
        largest = max(len(step.quads) for step in steps)
        batch = Batch(steps[0].entries[0].sequence, through, len(steps), len(quads), fresh, time.monotonic(),
                      Delta.of(quads, fresh), largest)  # fmt: skip
        held = self._held_triples()
        lanes = [lane for lane in self.lanes.values() if not self.builds.is_set_aside(lane.view)]
        in_step = [lane for lane in lanes if lane.in_step()]
        for lane in lanes:
            behind = lane not in in_step and held + len(quads) > LANES_MAX_HELD_TRIPLES
            lane.hand(batch.without_triples() if behind else batch)
        self.progress.dispatched = through
        if largest <= SMALL_BATCH_TRIPLES:  # after an import (a large step) the next posts are handed out at once:
            self._wait_in_step(in_step, through)  # they go ahead of it in the views that let them (`lanes.py`)

    def _held_triples(self) -> int:
        """The triples of the batches the lanes hold (each batch once: the lanes share it)."""
        held = {id(batch): batch.triples for lane in self.lanes.values() for batch in lane.held() if batch.delta}
        return sum(held.values())

    def _wait_in_step(self, lanes: list[ViewLane], through: int) -> None:
        first_done: float | None = None
        while not self.stopping.is_set():
            done = [lane.cursor.value >= through or self.builds.is_set_aside(lane.view) for lane in lanes]
            if all(done):
                return
            now = time.monotonic()
            if any(done):
                first_done = first_done or now
                if now - first_done >= HOLD_SECONDS:
                    return
            lanes[done.index(False)].cursor.wait_for(through, 0.05)

    def _wait_lanes_idle(self) -> None:
        for lane in self.lanes.values():
            while not lane.wait_idle(1.0):
                if self.stopping.is_set():
                    return

    def _build_all(self, through: int) -> None:
        """Every view built again through `through` (after a failure outside any one view's update)."""
        self._wait_lanes_idle()
        self.builds.build_all(self.views, through)
        for lane in self.lanes.values():
            lane.drop(through)
            lane.cursor.advance(through)
        self.progress.dispatched = max(self.progress.dispatched, through)
        self.lane_advanced()

    def _rebuild_all(self, erased_at: int) -> int:
        current = self.builds.rebuild_all(self.views, erased_at)
        for lane in self.lanes.values():
            lane.cursor.advance(current)
        return current
