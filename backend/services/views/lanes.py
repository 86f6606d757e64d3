"""One lane per kept view: the batches it has yet to take, how far through the journal it is, and the thread that
updates it, so that each view advances at its own pace.

The keeper hands every batch of applied steps to every lane. Lanes in step take the same batch (one `Delta`,
whose answers from the store the views share) and the keeper waits for them, so in the common case the views
move together as before. A view slow on a large batch (an import of 100,000 triples, for the graph index or the
SHACL findings) is let go after `HOLD_SECONDS` (`keeper.py`): the others take the next posts meanwhile, and it
takes every batch it missed as one once it is done. Before lanes, such an import held every view's next rows
back until the slowest view was through with it: a robot's messages were missing from the conversations report
for 20 s after a 122,000-triple import, though that report had caught up on the import itself.

How many views update at once is bounded by `Turns`: on the embedded store the views' work is this process's
CPU, which the posts need too. A batch of a few triples (a post) has a turn of its own beside the others, so
fresh posts never wait for two views that chew on an import; and the views waiting for a turn take it cheapest
first (their batch's triples times what a triple has cost that view so far), so a cheap report is not kept behind
an expensive index. The reports come before the other views (`served_first`): their lag is what readiness and
the ingest's pace watch, and a robot's messages are in the conversations report within a second of their 201
even right after a large import, while the graph, the timeline and the findings are still taking it in."""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from segb_server.backend.services.reports.folder import FOLDER as REPORTS_FOLDER
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.writing.cursor import Cursor

if TYPE_CHECKING:
    from segb_server.backend.services.views.view import KeptView

logger = logging.getLogger("segb.views")

# A batch of at most this many triples is small: a post or a few. It may take the express turn, which is kept
# for such batches, so the views of fresh posts never wait behind views busy with a large batch.
SMALL_BATCH_TRIPLES = 5_000
# Batches a lane merges into one update when it is behind: as many steps as the keeper's own batches hold, so
# that an update of a lane catching up ends about as soon as one in step.
MERGED_STEPS = 100
OUTAGE_RETRY_SECONDS = 1.0


@dataclass(eq=False)
class Batch:
    """Applied journal steps handed to every lane: entries `first`…`through`, their triples as one `Delta` shared
    by the lanes (None: read back from the journal when a lane's turn comes, so that lanes far behind do not
    hold every post's triples), the IRIs among them the store never held before (`fresh`), and when the
    oldest step was applied (`time.monotonic()`)."""

    first: int
    through: int
    steps: int
    triples: int
    fresh: frozenset[str]
    since: float
    delta: Delta | None

    def without_triples(self) -> Batch:
        return Batch(self.first, self.through, self.steps, self.triples, self.fresh, self.since, None)


@dataclass
class ViewTime:
    """What keeping one view current has cost this process so far: the CPU seconds of its updates (their lane's
    own thread, so the other views' and the requests' work is not counted), their wall seconds, the batches they
    took and their triples (`python -m bench.views_cpu` reads it; the log says it per batch at DEBUG)."""

    cpu: float = 0.0
    wall: float = 0.0
    batches: int = 0
    triples: int = 0

    def cost_of(self, triples: int) -> float:
        """What `triples` more are likely to take this view (seconds; 0 for a view that has taken none yet)."""
        return self.wall / self.triples * triples if self.triples else 0.0


def served_first(view: str) -> bool:
    """Whether a view's lane goes before the others waiting for a general turn: the reports'."""
    return view.startswith(f"{REPORTS_FOLDER}/")


class Turns:
    """Who may update a view now: `general` turns for any batch and `express` turns for small ones only. Of the
    lanes waiting, those served first before the others, then the cheapest batch."""

    def __init__(self, general: int, express: int) -> None:
        self._free = {"general": general, "express": express}
        self._waiting: list[tuple[int, float, int, bool]] = []  # (rank, cost, arrival, small)
        self._arrivals = itertools.count()
        self._changed = threading.Condition()

    @contextmanager
    def turn(self, cost: float, small: bool, first: bool = False) -> Iterator[None]:
        with self._changed:
            me = (0 if first else 1, cost, next(self._arrivals), small)
            self._waiting.append(me)
            self._changed.wait_for(lambda: self._kind_for(me) is not None)
            kind = self._kind_for(me)
            assert kind is not None
            self._waiting.remove(me)
            self._free[kind] -= 1
        try:
            yield
        finally:
            with self._changed:
                self._free[kind] += 1
                self._changed.notify_all()

    def _kind_for(self, me: tuple[int, float, int, bool]) -> str | None:
        """The turn `me` may take now: an express one when it is small and one is free; else a general one when
        one is free and no waiter for a general turn is ranked before it, has a cheaper batch, or the same and
        came first."""
        if me[3] and self._free["express"] > 0:
            return "express"
        if self._free["general"] <= 0:
            return None
        express_free = self._free["express"] > 0
        for other in self._waiting:
            if other is not me and not (other[3] and express_free) and other[:3] < me[:3]:
                return None
        return "general"


class LaneHost(Protocol):
    """What a lane needs of its keeper (the keeper is one): see `ViewKeeper` for each."""

    turns: Turns
    stopping: threading.Event

    def read_back(self, batch: Batch) -> Delta: ...
    def lane_failed(self, lane: ViewLane, error: BaseException) -> bool: ...
    def is_set_aside(self, lane: ViewLane) -> bool: ...
    def rebuild_due(self, lane: ViewLane) -> int | None: ...
    def rebuild(self, lane: ViewLane, through: int) -> None: ...
    def lane_advanced(self) -> None: ...


@dataclass(eq=False)
class ViewLane:
    """One view's batches to take, how far it is (`cursor`), and its thread."""

    view: KeptView
    host: LaneHost
    cursor: Cursor = field(default_factory=Cursor)
    spent: ViewTime = field(default_factory=ViewTime)
    _batches: deque[Batch] = field(default_factory=deque)
    outage: str | None = None  # the store's or state's error its update retries
    _busy: bool = False
    _changed: threading.Condition = field(default_factory=threading.Condition)
    _thread: threading.Thread | None = None

    @property
    def name(self) -> str:
        return self.view.name

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name=f"segb-view-{self.name}", daemon=True)
        self._thread.start()

    def wake(self) -> None:
        with self._changed:
            self._changed.notify_all()

    def join(self, timeout: float) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    def hand(self, batch: Batch) -> None:
        with self._changed:
            self._batches.append(batch)
            self._changed.notify_all()

    def held(self) -> list[Batch]:
        """The batches waiting, and the one being taken (a copy)."""
        with self._changed:
            return list(self._batches)

    def in_step(self) -> bool:
        """Nothing waits in this lane and nothing is under way: it takes the next batch as soon as it comes."""
        with self._changed:
            return not self._batches and not self._busy

    def wait_idle(self, timeout: float | None = None) -> bool:
        with self._changed:
            return self._changed.wait_for(lambda: not self._batches and not self._busy, timeout)

    def drop(self, through: int) -> None:
        """Forget the batches a build through `through` includes (their last entry at or before it)."""
        with self._changed:
            self._batches = deque(batch for batch in self._batches if batch.through > through)
            self._changed.notify_all()

    # --- the lane's thread ------------------------------------------------------------------------------

    def _run(self) -> None:
        while not self.host.stopping.is_set():
            if self.host.is_set_aside(self):  # its batches are not taken: a build takes in all they hold
                self._rebuild_when_due()
                continue
            taken = self._take()
            if taken is None:
                continue
            try:
                if not self._update(taken):
                    return
            finally:
                with self._changed:
                    for _ in taken:
                        self._batches.popleft()
                    self._busy = False
                    self._changed.notify_all()
            self.host.lane_advanced()

    def _rebuild_when_due(self) -> None:
        through = self.host.rebuild_due(self)
        if through is None:
            self.host.stopping.wait(0.1)
            return
        with self.host.turns.turn(0.0, small=False):
            self.host.rebuild(self, through)
        self.drop(through)
        self.host.lane_advanced()

    def _take(self) -> list[Batch] | None:
        """The next batches to take as one update (at most MERGED_STEPS steps), marked as under way; None when
        there are none after a short wait (the loop then looks for a rebuild or a stop)."""
        with self._changed:
            if not self._changed.wait_for(lambda: self._batches or self.host.stopping.is_set(), timeout=0.25):
                return None
            if self.host.stopping.is_set():
                return None
            count = steps = 0
            for batch in self._batches:
                count, steps = count + 1, steps + batch.steps
                if steps >= MERGED_STEPS:
                    break
            self._busy = True
            return list(itertools.islice(self._batches, count))

    def _update(self, taken: list[Batch]) -> bool:
        """Update the view with `taken`, retrying while the store is away; False when stopping meanwhile."""
        triples = sum(batch.triples for batch in taken)
        while True:
            try:
                delta = self._delta_of(taken)
                cost = self.spent.cost_of(triples)
                small, first = triples <= SMALL_BATCH_TRIPLES, served_first(self.name)
                with self.host.turns.turn(cost, small=small, first=first):
                    wall, cpu = _timed(self.view.update, delta, taken[-1].through)
            except Exception as error:
                if self.host.lane_failed(self, error):  # an outage: the same batches again, in a while
                    if self.host.stopping.wait(OUTAGE_RETRY_SECONDS):
                        return False
                    continue
                return True  # set aside: built again later (its batches are dropped then)
            self.outage = None
            spent = self.spent
            spent.cpu, spent.wall = spent.cpu + cpu, spent.wall + wall
            spent.batches, spent.triples = spent.batches + 1, spent.triples + triples
            self.cursor.advance(taken[-1].through)
            if logger.isEnabledFor(logging.DEBUG):
                logger.debug("view %s through entry %d: %d triples in %.3f s", self.name, taken[-1].through, triples,
                             wall)  # fmt: skip
            return True

    def _delta_of(self, taken: list[Batch]) -> Delta:
        """One batch's own `Delta` (shared with the lanes in step), or the batches' triples as one."""
        if len(taken) == 1 and taken[0].delta is not None:
            return taken[0].delta
        deltas = [batch.delta if batch.delta is not None else self.host.read_back(batch) for batch in taken]
        return Delta.of(
            [quad for delta in deltas for quad in delta.quads], frozenset().union(*(d.fresh for d in deltas))
        )


def _timed(update: Callable[[Delta, int], None], delta: Delta, through: int) -> tuple[float, float]:
    """`update(delta, through)`, and the seconds it took: on the clock, and of its thread's CPU."""
    began, cpu = time.perf_counter(), time.thread_time()
    update(delta, through)
    return time.perf_counter() - began, time.thread_time() - cpu
