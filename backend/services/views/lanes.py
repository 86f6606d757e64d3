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
an expensive index (`turns.py`: the reports come before the other views).

A view whose rows are read again from the store key by key (`GoesAhead`: the reports, the timeline's kinds and
the SPARQL rules) does not make the posts behind a large batch wait for it: they go ahead of it while it waits
for its turn, and between the parts of its keys. A robot's messages are then in the conversations report within
a second of their 201 even right after a large import."""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Protocol

from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.turns import Turns, served_first
from segb_server.backend.services.views.view import GoesAhead
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
# How long a lane with a large batch waits for a general turn before it looks again for posts to take ahead.
AHEAD_WAIT_SECONDS = 0.05


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
    largest: int = 0  # the triples of its largest step: an import is one large step, posts are many small ones

    def without_triples(self) -> Batch:
        return Batch(self.first, self.through, self.steps, self.triples, self.fresh, self.since, None, self.largest)


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
    _goes_ahead: bool = False  # the view lets posts go ahead of a large batch (`GoesAhead`)
    _ahead_through: int = 0  # the last entry taken ahead of a large batch not yet taken in (kept past a retry)

    def __post_init__(self) -> None:
        self._goes_ahead = isinstance(self.view, GoesAhead)  # once: a protocol's isinstance reads every member

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
            self._ahead_through = 0 if self._ahead_through <= through else self._ahead_through
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
                if count and self._goes_ahead and _large(batch) != _large(self._batches[0]):
                    break  # a large batch alone: the posts behind it go ahead of it (`_update_letting_ahead`)
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
                through = taken[-1].through
                if self._goes_ahead and any(map(_large, taken)):
                    wall, cpu, through = self._update_letting_ahead(delta, taken, cost, first)
                else:
                    with self.host.turns.turn(cost, small=small, first=first):
                        wall, cpu = _timed(self.view.update, delta, through)
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
            self.cursor.advance(through)
            if logger.isEnabledFor(logging.DEBUG):
                logger.debug("view %s through entry %d: %d triples in %.3f s", self.name, through, triples,
                             wall)  # fmt: skip
            return True

    # --- small batches ahead of a large one ------------------------------------------------------------

    def _update_letting_ahead(
        self, delta: Delta, taken: list[Batch], cost: float, first: bool
    ) -> tuple[float, float, int]:
        """Update the view with a large batch while the small ones queued behind it go ahead: while it waits for a
        general turn, and between the parts of its keys. Its position then includes both (they are all in the
        store, and the view reads its keys from there: `GoesAhead`)."""
        view = self.view
        assert isinstance(view, GoesAhead)
        ahead = [taken[-1].through, self._ahead_through]

        def let_ahead(turn: bool) -> int:
            queued = self._queued_small(taken)
            if queued:
                with self.host.turns.turn(0.0, small=True, first=first) if turn else nullcontext():
                    wall, cpu = _timed(view.update_ahead, self._delta_of(queued), queued[-1].through)
                self._taken_ahead(queued, wall, cpu)
                ahead.append(queued[-1].through)
                self._ahead_through = max(ahead)
            return max(ahead)

        ticket = self.host.turns.ticket(cost, small=False, first=first)
        while True:
            let_ahead(turn=True)
            with self.host.turns.turn_within(ticket, AHEAD_WAIT_SECONDS) as granted:
                if granted:
                    wall, cpu = _timed(partial(view.update_in_parts, between=partial(let_ahead, turn=False)),
                                       delta, taken[-1].through)  # fmt: skip
                    self._ahead_through = 0  # the view's position now includes them
                    return wall, cpu, max(ahead)

    def _queued_small(self, taken: list[Batch]) -> list[Batch]:
        """The batches of posts queued right behind `taken` (as many steps as one update takes)."""
        with self._changed:
            queued: list[Batch] = []
            for batch in itertools.islice(self._batches, len(taken), None):
                if _large(batch) or sum(b.steps for b in queued) + batch.steps > MERGED_STEPS:
                    break
                queued.append(batch)
            return queued

    def _taken_ahead(self, queued: list[Batch], wall: float, cpu: float) -> None:
        with self._changed:
            done = {id(batch) for batch in queued}
            self._batches = deque(batch for batch in self._batches if id(batch) not in done)
        spent = self.spent
        spent.cpu, spent.wall = spent.cpu + cpu, spent.wall + wall
        spent.batches, spent.triples = spent.batches + 1, spent.triples + sum(batch.triples for batch in queued)
        if logger.isEnabledFor(logging.DEBUG):
            logger.debug("view %s: entries %d-%d ahead of a large batch, in %.3f s", self.name, queued[0].first,
                         queued[-1].through, wall)  # fmt: skip

    def _delta_of(self, taken: list[Batch]) -> Delta:
        """One batch's own `Delta` (shared with the lanes in step), or the batches' triples as one."""
        if len(taken) == 1 and taken[0].delta is not None:
            return taken[0].delta
        deltas = [batch.delta if batch.delta is not None else self.host.read_back(batch) for batch in taken]
        return Delta.of(
            [quad for delta in deltas for quad in delta.quads], frozenset().union(*(d.fresh for d in deltas))
        )


def _large(batch: Batch) -> bool:
    """Whether the batch holds a large step (an import), which the posts behind it may go ahead of."""
    return batch.largest > SMALL_BATCH_TRIPLES


def _timed(update: Callable[[Delta, int], None], delta: Delta, through: int) -> tuple[float, float]:
    """`update(delta, through)`, and the seconds it took: on the clock, and of its thread's CPU."""
    began, cpu = time.perf_counter(), time.thread_time()
    update(delta, through)
    return time.perf_counter() - began, time.thread_time() - cpu
