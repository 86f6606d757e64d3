"""Keeping views of the graph current from the journal's stream of new triples.

A view (a report's rows, the graph index) is a `KeptView`: built once from the whole store, then updated
from what each applied journal step added, and emptied by a clearing. The `ViewKeeper` runs them all in one
background thread fed by the applier, so every view follows the same stream in the same order. A view
records the journal sequence it includes: after a restart it catches up from the journal instead of being
built again. Before a batch reaches the views, the registry of the IRIs the store holds (`seen_terms.py`) takes
it, and tells them which of the batch's IRIs are fresh: joins from those are followed among the batch's triples.

On a remote store the views of one batch are updated side by side, each in a worker thread of its own: their
work is mostly waiting for the store's answers (a round trip per query), so a batch takes as long as its
slowest view rather than all of them added up. On the embedded store the same work is this process's own CPU,
which the posts need too: two views go side by side there. The store works out an answer without holding the
interpreter (`store/solutions.py`), so one view's query runs on one core while another view's Python runs on
the other; a single thread left a core idle while the views fell behind (a soak of one robot: the views 22 s
behind after a minute, 1.3 s with two).

With several API processes on one data directory, only the one holding the data directory's leadership keeps
the views; the others follow the views it stores, which they read to answer. When the leader goes, the
process that takes over catches the views up from the journal and keeps them. The views' keeper is usually
the applier too, and gets its steps as they are applied; on a host whose processes do not apply (the state is
in PostgreSQL and another host's process applies), it reads them from the journal as the store's cursor
advances.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

from pyoxigraph import Quad

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.ops.leadership import Lead, Leadership
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.seen_terms import SeenTerms
from segb_server.backend.services.writing.applier import Applied, Applier, applied_steps, quads_of
from segb_server.backend.services.writing.cursor import Cursor
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.state.database import StateUnavailable
from segb_server.backend.store.base import Store, StoreUnavailable

logger = logging.getLogger("segb.views")

# Applied steps handled together: one update per view for a burst of posts. At most 100, so that a batch of the
# embedded store's views, below the requests' priority on a busy server, ends within about half a second: posts
# wait for the views past VIEWS_MAX_LAG_SECONDS, and a batch under way is what the lag overshoots that by (200
# steps: reports_lag p99 2.04 s, max 2.98, in a 15-minute soak of one robot; the views' CPU is per triple, not
# per batch, there).
BATCH_STEPS = 100
# After a batch, the thread rests this many times as long as the batch took before taking the next: under a
# steady stream of posts the views then use at most half of the time (and of the store's), the next batch
# holds more posts for the same number of queries, and requests keep their share of the cores. Never longer
# than MAX_REST_SECONDS: after a slow batch a long rest would let the next one grow, and the views fall behind.
REST_RATIO = 1.0
MAX_REST_SECONDS = 0.25
# Nor does a rest keep a step waiting longer than this since it was applied: a post's rows are due in its
# reports within a second of its answer, and a slow batch (a large store, busy cores) already takes a share
# of that. The rest is then cut short, and only while batches are that slow.
START_WITHIN_SECONDS = 0.4
# Nor does the thread rest while the views are this far behind (the oldest step waiting, seconds): under more
# posts than the views keep up with at half the time, they take the time they need, and the posts slow down
# rather than the views falling behind without end.
NO_REST_BEHIND_SECONDS = 1.0
EMBEDDED_VIEW_WORKERS = 2  # views updated side by side on the embedded store (see the module's docstring)
FOLLOW_SECONDS = 0.25  # how often a following process reads how far the leader's views are
PULL_SECONDS = 0.05  # where another process applies, how often the views read the store's cursor while caught up
# Applied steps wait in the queue with their triples up to this many; past it, a step waits as its journal
# entries' numbers and its triples are read back from the journal when its turn comes, so memory stays bounded
# however far the views fall behind (a burst of posts, a slow store).
MAX_QUEUED_TRIPLES = 20_000
# A view whose build failed on its own (its query refused by the store, a bug) is set aside and built again
# this often; the others are kept current meanwhile, and its report is evaluated in full.
RETRY_BUILD_SECONDS = 2.0


class KeptView(Protocol):
    name: str
    ready: bool  # built (or caught up) since this server started: its answers can be served

    def stored_through(self) -> int | None:
        """The journal sequence the stored view includes, or None when it must be built (absent, or made by
        another version of the view)."""

    def build(self, through: int) -> None:
        """Make the view from the whole store, which holds the journal through `through`."""

    def update(self, delta: Delta, through: int) -> None:
        """Add what the triples of `delta` (just added to the store) change; the view then includes the journal
        through `through`."""

    def clear(self, through: int) -> None:
        """The graph was emptied at `through`."""

    def follow(self) -> int | None:
        """Read the view as another process keeps it (never writing): the journal sequence it includes, or
        None while it is not there to be read."""

    def prepared(self) -> None:
        """The view was built or caught up at start, and answers from now on (a view may get ready to answer
        its first request here)."""


@runtime_checkable
class ForgetsErased(Protocol):
    """A view that keeps, past a clearing, what an erasure must remove (a table of terms, a change log)."""

    def forget_erased(self) -> None:
        """Called after every view was cleared for an erasure, before they are built again."""


@dataclass
class ViewTime:
    """What keeping one view current has cost this process so far: the CPU seconds of its updates (their worker
    thread's own, so the other views' and the requests' work is not counted), their wall seconds, and the
    batches they took (`python -m bench.views_cpu` reads it; the log says it per batch at DEBUG)."""

    cpu: float = 0.0
    wall: float = 0.0
    batches: int = 0


@dataclass
class _Marker:
    done: threading.Event


@dataclass(frozen=True)
class _Unread:
    """An applied step whose triples the queue did not keep (past MAX_QUEUED_TRIPLES): read from the journal."""

    first: int
    last: int


@dataclass(frozen=True)
class _Waiting:
    """A step or a marker in the queue, with when it was queued (`time.monotonic()`)."""

    item: Applied | _Unread | _Marker
    since: float


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
        self._applier = applier if applier is not None and applier.leadership is not self.leadership else None
        self.rest_ratio = rest_ratio
        self._housekeeping = housekeeping
        self._queue: queue.Queue[_Waiting | None] = queue.Queue()
        self._queued_triples = 0  # held by the steps in the queue
        self._max_queued_triples = max_queued_triples
        self.most_queued_triples = 0  # the most the queue has held (what its memory is bounded by)
        self._queued_lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stopping = threading.Event()  # ends retry waits too: a store that never returns must not hold shutdown
        self.outage: str | None = None  # the error of the store or state being retried (all views wait)
        # Every view is being built from the store (at start, or again after an erasure): their lag is that build's,
        # not posts outpacing their upkeep. Written by the keeper's thread, read by requests.
        self.building_all = False
        # view → the error its last build failed with. Written by the keeper's thread, read by requests (readiness):
        # replaced, never changed in place, so a reader always holds a whole one.
        self._set_aside: dict[str, str] = {}
        self._retry_at = 0.0  # when the views set aside are built again (time.monotonic())
        self.cursor = Cursor()  # the journal entry every view is current through
        self._spent = {view.name: ViewTime() for view in views}  # written by the keeper's thread only
        workers = max(1, len(views)) if store.remote else EMBEDDED_VIEW_WORKERS
        self._workers = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="segb-view")

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="segb-views", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stopping.set()
        self._queue.put(None)
        if self._thread is not None:
            self._thread.join(timeout=30)
        self._workers.shutdown(wait=True)
        if self.seen_terms is not None:
            self.seen_terms.close()

    def on_applied(self, step: Applied) -> None:
        """The applier's listener: called in the applier's thread, so it only queues."""
        with self._queued_lock:
            kept = self._queued_triples + len(step.quads) <= self._max_queued_triples
            if kept:
                self._queued_triples += len(step.quads)
                self.most_queued_triples = max(self.most_queued_triples, self._queued_triples)
        item = step if kept else _Unread(step.entries[0].sequence, step.entries[-1].sequence)
        self._queue.put(_Waiting(item, time.monotonic()))

    def wait_until_current(self, timeout: float) -> bool:
        """Wait until every step applied so far is in the views."""
        done = threading.Event()
        self._queue.put(_Waiting(_Marker(done), time.monotonic()))
        return done.wait(timeout)

    def wait_for(self, sequence: int, timeout: float) -> bool:
        """Wait until the views include journal entry `sequence` (True), or `timeout` seconds passed."""
        return self.cursor.wait_for(sequence, timeout, reached=self._served_from_views)

    def _served_from_views(self) -> bool:
        """Every view is ready, but those set aside (tried again later; their reports are evaluated in full)."""
        return all(view.ready or view.name in self._set_aside for view in self.views)

    def view_times(self) -> dict[str, ViewTime]:
        """Each view's updates so far (a copy)."""
        return {name: replace(spent) for name, spent in self._spent.items()}

    @property
    def through(self) -> int:
        """The journal entry every view is current through."""
        return self.cursor.value

    def lag(self, applied: int) -> tuple[int, float]:
        """Journal entries the store has and the views do not have yet, and how long the oldest of them has
        waited (seconds); nothing before the views are first ready: until then they are not what answers."""
        through = self.through
        behind = self._behind(applied, through)
        return behind, self.journal.age_of(through + 1) if behind else 0.0

    def building(self, applied: int) -> list[str]:
        """The views not ready yet (built at start, or rebuilt) while the store holds entries they do not:
        what reads them answers from the store meanwhile, or (the findings) says it is building. None when
        there is nothing they miss (an empty store: nothing to build)."""
        if applied <= self.through and not self._set_aside:
            return []
        return [view.name for view in self.views if not view.ready]

    def behind(self, applied: int) -> int:
        """Journal entries the store has through `applied` and the views do not (0 before they are ready)."""
        return self._behind(applied, self.through)

    def _behind(self, applied: int, through: int) -> int:
        if not any(view.ready for view in self.views):
            return 0
        return max(0, applied - through)

    def pending(self, applied: int, limit: int) -> list[Quad] | None:
        """The triples the store has through entry `applied` and the views do not have yet, read from the journal
        (a reader adds them to what a view holds to answer as the store would); None when they cannot stand in
        for the store: a clearing is among those entries, or more than `limit` of them."""
        behind = self._behind(applied, self.through)
        if behind == 0:
            return []
        if behind > limit:
            return None
        steps = applied_steps(self.journal.entries_after(applied - behind, behind))
        if any(step.cleared or step.erased for step in steps):
            return None
        return [quad for step in steps for quad in step.quads]

    # --- the thread ----------------------------------------------------------------------------------

    def _run(self) -> None:
        while not self.leadership.try_acquire():
            self._follow()
            if self._stopping.wait(FOLLOW_SECONDS):
                return
        while True:
            try:
                self.building_all = True
                self._prepare_all()
                self.outage = None
                break
            except OUTAGES as error:
                self.outage = str(error)
                logger.warning("building the views failed (%s); retrying", error)
            finally:
                self.building_all = False
            if self._stopping.wait(2):
                return
        if self._housekeeping is not None:
            try:
                self._housekeeping()
            except Exception:  # leftovers stay for the next start; the views are kept current meanwhile
                logger.exception("tidying the views' storage failed")
        rested = 0.0  # when the rest after the last batch ends (time.monotonic())
        while True:
            steps = self._next_steps(rested)
            if steps is None:
                return
            if self._set_aside and time.monotonic() >= self._retry_at:
                self._build_set_aside()
            applied = [step for step in steps if not isinstance(step, _Marker)]
            began = time.monotonic()
            if applied and not self._process_retrying(applied):
                return
            for marker in steps:
                if isinstance(marker, _Marker):
                    marker.done.set()
            ended = time.monotonic()
            resting = applied and self.rest_ratio > 0 and self._waited() < NO_REST_BEHIND_SECONDS
            rested = ended + min(MAX_REST_SECONDS, self.rest_ratio * (ended - began)) if resting else 0.0

    def _next_steps(self, rested: float) -> list[Applied | _Unread | _Marker] | None:
        """What to do next, once the rest ending at `rested` is over (or the first step waiting has waited
        START_WITHIN_SECONDS): what the applier queued, or (where another process applies) what the journal
        holds up to the store's cursor. None when stopping."""
        if self._applier is not None:
            return self._next_pulled(rested)
        wait = max(0.0, self._retry_at - time.monotonic()) if self._set_aside else None
        try:
            first = self._queue.get(timeout=wait)
        except queue.Empty:
            return []
        if first is None:
            return None
        if self._stopping.wait(max(0.0, min(rested, first.since + START_WITHIN_SECONDS) - time.monotonic())):
            return None
        items: list[Applied | _Unread | _Marker] = [first.item]
        while not self._queue.empty() and len(items) < BATCH_STEPS:
            if (waiting := self._queue.get()) is None:
                return None
            items.append(waiting.item)
        with self._queued_lock:
            self._queued_triples -= sum(len(item.quads) for item in items if isinstance(item, Applied))
        return items

    def _next_pulled(self, rested: float) -> list[Applied | _Unread | _Marker] | None:
        """Where another process applies (the views' own process, a host that does not apply): the journal's
        entries up to the store's cursor, which is read every PULL_SECONDS while there is nothing new. The same
        rest as for steps this process applied, cut short as START_WITHIN_SECONDS says. None when stopping."""
        rest = rested - time.monotonic()
        if rest > 0 and self._stopping.wait(min(rest, max(0.0, START_WITHIN_SECONDS - self._waited()))):
            return None
        while True:
            markers: list[Applied | _Unread | _Marker] = []
            while not self._queue.empty():  # `wait_until_current`'s, answered once what is applied now is in
                if (waiting := self._queue.get()) is None:
                    return None
                markers.append(waiting.item)
            steps = self._pulled()
            if steps or markers or self._set_aside:
                return [*steps, *markers]
            if self._stopping.wait(PULL_SECONDS):
                return None

    def _waited(self) -> float:
        """How long the oldest step the views miss has waited (seconds; 0 when none waits): the oldest in the
        queue, or (where another process applies) the oldest journal entry applied and not viewed."""
        if self._applier is not None:
            if self._applier.applied <= self.through:
                return 0.0
            try:
                return self.journal.age_of(self.through + 1)
            except OUTAGES:
                return 0.0
        with self._queue.mutex:
            head = self._queue.queue[0] if self._queue.queue else None
        return 0.0 if head is None else time.monotonic() - head.since

    def _read_unread(self, items: list[Applied | _Unread]) -> list[Applied]:
        """The steps with each run of unread ones read from the journal (one read a run)."""
        steps: list[Applied] = []
        run: list[_Unread] = []
        for item in [*items, None]:
            if isinstance(item, _Unread) and (not run or item.first == run[-1].last + 1):
                run.append(item)
                continue
            if run:
                steps += applied_steps(self.journal.entries_after(run[0].first - 1, run[-1].last - run[0].first + 1))
                run = []
            if isinstance(item, _Unread):
                run.append(item)
            elif item is not None:
                steps.append(item)
        return steps

    def _pulled(self) -> list[Applied]:
        """The steps the store has and the views do not, read from the journal (at most BATCH_STEPS), once the
        store's cursor is read again (it is the applying process's)."""
        assert self._applier is not None
        if self._applier.leadership.held:
            return []  # this process applies: its steps come through the queue
        try:
            behind = self._applier.follow() - self.through
            steps = (
                applied_steps(self.journal.entries_after(self.through, min(behind, BATCH_STEPS))) if behind > 0 else []
            )
        except OUTAGES as error:  # read again at the next turn
            self.outage = str(error)
            return []
        self.outage = None
        return steps

    def _read_back(self, before: int) -> list[Applied]:
        """The journal's entries after the views' and before `before`, as steps; from the last clearing when
        one is among them (what came earlier, it removed)."""
        start = self.through
        cleared = self.journal.last_clearing()
        if start < cleared < before:
            start = cleared - 1
        return applied_steps(self.journal.entries_after(start, before - 1 - start))

    def _process_retrying(self, applied: list[Applied | _Unread]) -> bool:
        """Process `applied`, retrying while the store is away; False when stopped meanwhile."""
        while True:
            try:
                self._process(applied)
                self.outage = None
                return True
            except OUTAGES as error:
                self.outage = str(error)
                logger.warning("keeping the views current failed (%s); retrying", error)
                if self._stopping.wait(1):
                    return False
            except Exception:
                logger.exception("keeping the views current failed; building them again")
                last = applied[-1]
                through = last.last if isinstance(last, _Unread) else last.entries[-1].sequence
                try:
                    if self.seen_terms is not None:
                        self.seen_terms.build(self.store, through)
                    for view in self.views:
                        self._build_or_set_aside(view, through)
                except OUTAGES as outage:  # the thread lives on: the batch is tried again
                    self.outage = str(outage)
                    logger.warning("building the views again failed (%s); retrying", outage)
                    if self._stopping.wait(1):
                        return False
                    continue
                self.outage = None
                self._advance(through)
                return True

    def _follow(self) -> None:
        try:
            stored = [view.follow() for view in self.views]
        except Exception as error:  # e.g. the leader is building a view of another version just now
            self.outage = str(error)
            return
        self.outage = None
        for view, through in zip(self.views, stored, strict=True):
            view.ready = through is not None
        known = [through for through in stored if through is not None]
        if len(known) == len(stored):
            self._advance(min(known))

    def _prepare_all(self) -> None:
        """Build each view never built (or of another version) and catch up the others, through the entry the
        store holds now. A view failing on its own (a bug, its query refused) is set aside, built again later,
        and the next ones prepared all the same: a dead views' thread or one view holding the others back would
        leave every report behind for good. A store away stops them all (tried again as a whole)."""
        current = self.store.applied_through() or 0
        if self.seen_terms is not None:
            self._prepare_seen_terms(self.seen_terms, current)
        for view in self.views:
            if view.ready and view.stored_through() == current:
                continue  # prepared by an earlier try, which the store's outage ended
            try:
                self._prepare(view, current)
            except Exception as error:  # this view's own (its query refused or too slow, a bug), or an outage
                self._set_aside_unless_away(view, error)
                continue
            self._put_back(view)
        self._advance(current)

    def _set_aside_unless_away(self, view: KeptView, error: BaseException) -> None:
        """Set `view` aside for `error`, or raise it when the store or the views' storage is away (every view
        waits for them, tried again as a whole). A store that answers a ping was not away: the view's query
        failed on its own (e.g. it ran past the store's time limit)."""
        if isinstance(error, StateUnavailable) or (isinstance(error, StoreUnavailable) and not self._store_answers()):
            raise error
        self._set_view_aside(view, error)

    def _store_answers(self) -> bool:
        try:
            self.store.ping()
        except Exception:
            return False
        return True

    def _set_view_aside(self, view: KeptView, error: BaseException) -> None:
        if isinstance(error, OUTAGES):
            logger.warning("view %s failed (%s); set aside, built again in %g s", view.name, error, RETRY_BUILD_SECONDS)
        else:
            logger.error(
                "view %s failed; set aside, built again in %g s", view.name, RETRY_BUILD_SECONDS, exc_info=error
            )
        view.ready = False
        self._set_aside = {**self._set_aside, view.name: f"{view.name}: {error}"}
        self._retry_at = time.monotonic() + RETRY_BUILD_SECONDS

    def _put_back(self, view: KeptView) -> None:
        """`view` is built or caught up: it answers from now on (and is no longer set aside)."""
        if view.name in self._set_aside:
            self._set_aside = {name: error for name, error in self._set_aside.items() if name != view.name}
        view.prepared()
        view.ready = True

    def _build_or_set_aside(self, view: KeptView, through: int) -> None:
        """Build `view` through `through` (raising the store's outage), or set it aside when it fails on its
        own."""
        try:
            self._build(view, through)
        except Exception as error:
            self._set_aside_unless_away(view, error)
            return
        self._put_back(view)

    def _build_set_aside(self) -> None:
        """Build again, through where the others are, the views whose build failed."""
        for view in [view for view in self.views if view.name in self._set_aside]:
            try:
                self._build_or_set_aside(view, self.through)
            except OUTAGES as outage:  # the store away: the next turn tries again
                self._set_view_aside(view, outage)

    @property
    def last_error(self) -> str | None:
        """What readiness tells as the views' error: the outage retried, else why the views set aside are not
        built (None when neither)."""
        return self.outage or "; ".join(self._set_aside.values()) or None  # one dict read: a whole one

    def _prepare(self, view: KeptView, current: int) -> None:
        stored = view.stored_through()
        if stored is None:
            self._build(view, current)
            return
        try:
            self._catch_up(view, stored, current)
        except OUTAGES:
            raise
        except Exception:  # as in `_process_retrying`: the thread must live on, and the view be current
            logger.exception("catching view %s up failed; building it again", view.name)
            self._build(view, current)

    def _prepare_seen_terms(self, seen: SeenTerms, current: int) -> None:
        """The registry of IRIs made to include the store through `current`, before any view's batch uses it."""
        stored = seen.stored_through()
        if stored is not None and stored >= current:
            return
        entries = [] if stored is None else self.journal.entries_after(stored, current - stored)
        if stored is None or any(entry.action != "ingest" for entry in entries):  # absent, or triples went
            seen.build(self.store, current)
        else:
            seen.admit(quads_of(entries), stored + 1, current)

    def _build(self, view: KeptView, through: int) -> None:
        started = time.perf_counter()
        view.build(through)
        logger.info("view %s built in %.1f s", view.name, time.perf_counter() - started)

    def _catch_up(self, view: KeptView, stored: int, current: int) -> None:
        """Apply what the store received while this server was not keeping the view current."""
        if stored >= current:
            return
        started = time.perf_counter()
        entries = self.journal.entries_after(stored, current - stored)
        if any(entry.action != "ingest" for entry in entries):  # a clearing or an erasure
            self._build(view, current)
            return
        view.update(Delta.of(quads_of(entries)), current)
        logger.info("view %s caught up from entry %d to %d in %.1f s", view.name, stored, current,
                    time.perf_counter() - started)  # fmt: skip

    def _process(self, items: list[Applied | _Unread]) -> None:
        if not self.views:  # KEEP_VIEWS=false: nothing to read or match; waiting for the views waits for the store
            last = items[-1]
            self._advance(last.last if isinstance(last, _Unread) else last.entries[-1].sequence)
            return
        steps = [step for step in self._read_unread(items) if step.entries[-1].sequence > self.through]
        if not steps:
            return
        first = steps[0].entries[0].sequence
        if first > self.through + 1:  # applied by another process before this one took over: read them back
            steps = [*self._read_back(first), *steps]
        through = steps[-1].entries[-1].sequence
        cleared = max((index for index, step in enumerate(steps) if step.cleared or step.erased), default=-1)
        if cleared >= 0:
            at = steps[cleared].entries[-1].sequence
            if steps[cleared].erased:  # triples went: the views are made again from the store
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
            steps = [step for step in steps[cleared + 1 :] if step.entries[-1].sequence > at]
        quads = [quad for step in steps for quad in step.quads]
        fresh = frozenset[str]()
        if self.seen_terms is not None and steps:  # registered before any view reads the batch
            fresh = self.seen_terms.admit(quads, steps[0].entries[0].sequence, through)
        delta = Delta.of(quads, fresh)  # matched by every view
        began = time.perf_counter()
        kept = [view for view in self.views if view.name not in self._set_aside]  # those are built again instead
        updates = [self._workers.submit(_timed, view.update, delta, through) for view in kept]
        # Every one finishes before an error is raised: a retry starts from a quiet state. A view failing on its
        # own (its query refused, a bug) is set aside and built again later; the store away has the batch retried.
        failures = [(view, error) for view, update in zip(kept, updates, strict=True) if (error := update.exception())]
        for view, error in failures:
            self._set_aside_unless_away(view, error)
        seconds: dict[str, float] = {}
        for view, update in zip(kept, updates, strict=True):
            if view.name in self._set_aside:
                continue
            wall, cpu = update.result()
            seconds[view.name] = wall
            spent = self._spent[view.name]
            spent.cpu, spent.wall, spent.batches = spent.cpu + cpu, spent.wall + wall, spent.batches + 1
        if logger.isEnabledFor(logging.DEBUG):
            slowest = sorted(seconds.items(), key=lambda item: -item[1])[:3]
            logger.debug("views through entry %d: %d steps, %d triples in %.3f s (slowest: %s)", through, len(steps),
                         len(quads), time.perf_counter() - began,
                         ", ".join(f"{name} {took:.3f} s" for name, took in slowest))  # fmt: skip
        self._advance(through)

    def _rebuild_all(self, erased_at: int) -> int:
        """After an erasure: every view emptied, then built from the store (which holds at least the journal
        through `erased_at`); until a view is built again its answers are not served (reports are evaluated by
        their queries meanwhile), so nothing erased is served from old rows. Returns where the views now are."""
        current = max(erased_at, self.store.applied_through() or 0)
        if self.seen_terms is not None:  # the erased IRIs' hashes go too
            self.seen_terms.build(self.store, current)
        for view in self.views:
            view.ready = False
            view.clear(erased_at)
        for view in self.views:  # what a clearing keeps (tables of terms, change logs) goes too
            if isinstance(view, ForgetsErased):
                view.forget_erased()
        for view in self.views:
            self._build_or_set_aside(view, current)
        return current

    def _advance(self, through: int) -> None:
        self.cursor.advance(through)


def _timed(update: Callable[[Delta, int], None], delta: Delta, through: int) -> tuple[float, float]:
    """`update(delta, through)`, and the seconds it took: on the clock, and of its thread's CPU."""
    began, cpu = time.perf_counter(), time.thread_time()
    update(delta, through)
    return time.perf_counter() - began, time.thread_time() - cpu
