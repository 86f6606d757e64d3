"""The applied steps waiting for the views' keeper: what the applier hands over as it applies (a queue bounded by
its triples), or, where another process applies, what the journal holds up to the store's cursor; taken in
batches of at most `BATCH_STEPS`, with the keeper's rest cut short for a step that has waited long enough."""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.writing.applier import Applied, Applier, applied_steps
from segb_server.backend.services.writing.journal import Journal

# Applied steps handled together: one update per view for a burst of posts. At most 100, so that a batch of the
# embedded store's views, below the requests' priority on a busy server, ends within about half a second: posts
# wait for the views past VIEWS_MAX_LAG_SECONDS, and a batch under way is what the lag overshoots that by (200
# steps: reports_lag p99 2.04 s, max 2.98, in a 15-minute soak of one robot; the views' CPU is per triple, not
# per batch, there).
BATCH_STEPS = 100
# The keeper's rest (keeper.py) never keeps a step waiting longer than this since it was applied: a post's rows
# are due in its reports within a second of its answer, and a slow batch (a large store, busy cores) already
# takes a share of that. The rest is then cut short, and only while batches are that slow.
START_WITHIN_SECONDS = 0.4
PULL_SECONDS = 0.05  # where another process applies, how often the views read the store's cursor while caught up
# Applied steps wait in the queue with their triples up to this many; past it, a step waits as its journal
# entries' numbers and its triples are read back from the journal when its turn comes, so memory stays bounded
# however far the views fall behind (a burst of posts, a slow store).
MAX_QUEUED_TRIPLES = 20_000


@dataclass
class Marker:
    done: threading.Event


@dataclass(frozen=True)
class Unread:
    """An applied step whose triples the queue did not keep (past MAX_QUEUED_TRIPLES): read from the journal."""

    first: int
    last: int


@dataclass(frozen=True)
class Waiting:
    """A step or a marker in the queue, with when it was queued (`time.monotonic()`)."""

    item: Applied | Unread | Marker
    since: float


class StepQueue:
    def __init__(
        self, journal: Journal, applier: Applier | None, stopping: threading.Event, max_queued_triples: int
    ) -> None:
        """`applier`: the applying process's, when it is another's (its steps are then read from the journal)."""
        self.journal = journal
        self._applier = applier
        self.stopping = stopping
        self._queue: queue.Queue[Waiting | None] = queue.Queue()
        self._queued_triples = 0  # held by the steps in the queue
        self._max_queued_triples = max_queued_triples
        self.most_queued_triples = 0  # the most the queue has held (what its memory is bounded by)
        self._queued_lock = threading.Lock()
        self.outage: str | None = None  # reading the journal or the store's cursor failed (read again next turn)

    def stop(self) -> None:
        self._queue.put(None)

    def on_applied(self, step: Applied) -> None:
        """The applier's listener: called in the applier's thread, so it only queues."""
        with self._queued_lock:
            kept = self._queued_triples + len(step.quads) <= self._max_queued_triples
            if kept:
                self._queued_triples += len(step.quads)
                self.most_queued_triples = max(self.most_queued_triples, self._queued_triples)
        item = step if kept else Unread(step.entries[0].sequence, step.entries[-1].sequence)
        self._queue.put(Waiting(item, time.monotonic()))

    def wait_until_current(self, timeout: float) -> bool:
        """Wait until every step applied so far is in the views."""
        done = threading.Event()
        self._queue.put(Waiting(Marker(done), time.monotonic()))
        return done.wait(timeout)

    def next_steps(self, rested: float, dispatched: int) -> list[Applied | Unread | Marker] | None:
        """What to do next, once the rest ending at `rested` is over (or the first step waiting has waited
        START_WITHIN_SECONDS): what the applier queued, or (where another process applies) what the journal
        holds up to the store's cursor. None when stopping."""
        if self._applier is not None:
            return self._next_pulled(rested, dispatched)
        first = self._queue.get()
        if first is None:
            return None
        if self.stopping.wait(max(0.0, min(rested, first.since + START_WITHIN_SECONDS) - time.monotonic())):
            return None
        items: list[Applied | Unread | Marker] = [first.item]
        while not self._queue.empty() and len(items) < BATCH_STEPS:
            if (waiting := self._queue.get()) is None:
                return None
            items.append(waiting.item)
        with self._queued_lock:
            self._queued_triples -= sum(len(item.quads) for item in items if isinstance(item, Applied))
        return items

    def _next_pulled(self, rested: float, dispatched: int) -> list[Applied | Unread | Marker] | None:
        """Where another process applies (the views' own process, a host that does not apply): the journal's
        entries up to the store's cursor, which is read every PULL_SECONDS while there is nothing new. The same
        rest as for steps this process applied, cut short as START_WITHIN_SECONDS says. None when stopping."""
        rest = rested - time.monotonic()
        if rest > 0 and self.stopping.wait(min(rest, max(0.0, START_WITHIN_SECONDS - self.waited(dispatched)))):
            return None
        while True:
            markers: list[Applied | Unread | Marker] = []
            while not self._queue.empty():  # `wait_until_current`'s, answered once what is applied now is in
                if (waiting := self._queue.get()) is None:
                    return None
                markers.append(waiting.item)
            steps = self._pulled(dispatched)
            if steps or markers:
                return [*steps, *markers]
            if self.stopping.wait(PULL_SECONDS):
                return None

    def waited(self, dispatched: int) -> float:
        """How long the oldest step the views miss has waited (seconds; 0 when none waits): the oldest in the
        queue, or (where another process applies) the oldest journal entry applied and not handed out."""
        if self._applier is not None:
            if self._applier.applied <= dispatched:
                return 0.0
            try:
                return self.journal.age_of(dispatched + 1)
            except OUTAGES:
                return 0.0
        with self._queue.mutex:
            head = self._queue.queue[0] if self._queue.queue else None
        return 0.0 if head is None else time.monotonic() - head.since

    def read_unread(self, items: list[Applied | Unread]) -> list[Applied]:
        """The steps with each run of unread ones read from the journal (one read a run)."""
        steps: list[Applied] = []
        run: list[Unread] = []
        for item in [*items, None]:
            if isinstance(item, Unread) and (not run or item.first == run[-1].last + 1):
                run.append(item)
                continue
            if run:
                steps += applied_steps(self.journal.entries_after(run[0].first - 1, run[-1].last - run[0].first + 1))
                run = []
            if isinstance(item, Unread):
                run.append(item)
            elif item is not None:
                steps.append(item)
        return steps

    def _pulled(self, dispatched: int) -> list[Applied]:
        """The steps the store has and the views were not handed, read from the journal (at most BATCH_STEPS),
        once the store's cursor is read again (it is the applying process's)."""
        assert self._applier is not None
        if self._applier.leadership.held:
            return []  # this process applies: its steps come through the queue
        try:
            behind = self._applier.follow() - dispatched
            steps = (
                applied_steps(self.journal.entries_after(dispatched, min(behind, BATCH_STEPS))) if behind > 0 else []
            )
        except OUTAGES as error:  # read again at the next turn
            self.outage = str(error)
            return []
        self.outage = None
        return steps

    def read_back(self, dispatched: int, before: int) -> list[Applied]:
        """The journal's entries after those handed out and before `before`, as steps; from the last clearing
        when one is among them (what came earlier, it removed)."""
        start = dispatched
        cleared = self.journal.last_clearing()
        if start < cleared < before:
            start = cleared - 1
        return applied_steps(self.journal.entries_after(start, before - 1 - start))
