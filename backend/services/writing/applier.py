"""The applier: journal entries written into the triple store, in order, in batches sized for the store.

The store remembers how far it is applied (Store.apply records the cursor with the triples), so after a crash,
a restart, or the store's own outage, applying resumes there; re-applying an entry changes nothing. A store
with no cursor (new, wiped, or from before the journal) is brought up from the last clearing. Whoever wants
entries applied calls `apply_pending` — the background thread, or a post that waits for its own entry — and
one at a time applies everything the journal holds.

With several API processes on one journal (`segb serve --workers N`, or hosts sharing a PostgreSQL state),
only the process holding the leadership applies; the others follow: they read the store's cursor instead, so
their readiness, backlog limit and `INGEST_ACK=store` waits see what the leader applied.

A leader among hosts (`SharedLeadership`) may lose the lead without knowing it for a moment (its database
connection cut). Its writes carry its apply epoch, and a newer leader claims the store for its own epoch before
it reads the store's cursor: from then on the store (and the journal's state) refuse the older one. The refused
applier stops where it is, mid-batch, says why, and steps down: it follows the new leader, which applies from
the cursor it read, so no step is written twice and none out of order.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from pyoxigraph import Quad, RdfFormat, parse

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.ops.leadership import Lead, Leadership, SharedLeadership
from segb_server.backend.services.writing.cursor import Cursor
from segb_server.backend.services.writing.journal import Journal, JournalEntry
from segb_server.backend.state.epochs import StateFenced
from segb_server.backend.store.base import Store, StoreFenced

logger = logging.getLogger("segb.applier")

ENTRIES_PER_READ = 500
FIRST_RETRY_SECONDS = 0.2
MAX_RETRY_SECONDS = 5.0
FENCED = (StoreFenced, StateFenced)  # a write of this applier's epoch refused: a newer leader applies
FOLLOW_SECONDS = 0.5  # how often a following process reads the store's cursor, and tries to take the lead
WAIT_POLL_SECONDS = 0.05  # how often a follower waiting for one entry (INGEST_ACK=store) asks the store


@dataclass(frozen=True)
class Applied:
    """What one step applied: its entries, and the triples they added (none for a clearing or an erasure).
    `erased`: the step was an erasure, which removed triples from the store: a view cannot follow it from the
    step's triples, and is built again from the store."""

    entries: list[JournalEntry]
    quads: list[Quad]
    cleared: bool
    erased: bool = False


Listener = Callable[[Applied], None]


def quads_of(entries: Sequence[JournalEntry]) -> list[Quad]:
    """The triples the entries added, parsed from their content."""
    return [quad for entry in entries if entry.content for quad in parse(entry.content, RdfFormat.N_TRIPLES)]


def applied_steps(entries: Sequence[JournalEntry]) -> list[Applied]:
    """Entries read back from the journal as the steps that applied them (one each)."""
    return [
        Applied([entry], quads_of([entry]), cleared=entry.action == "delete_all", erased=entry.action == "erase")
        for entry in entries
    ]


class Applier:
    def __init__(
        self,
        journal: Journal,
        store: Store,
        *,
        batch_triples: int,
        leadership: Lead | None = None,
    ) -> None:
        self.journal = journal
        self.store = store
        self.leadership = leadership or Leadership(None)
        self.batch_triples = batch_triples
        self.cursor = Cursor()  # the entry the store is known to be applied through
        # Whether the cursor is the store's own, read since start or the last outage; until it is, the
        # leader reads it before applying (the store may come back restored or wiped). What was last known
        # stays meanwhile: the backlog and the lag count from it, not from the journal's first entry.
        self._cursor_read = False
        self._epoch: int | None = None  # the apply epoch the store was claimed for (None: no shared leadership)
        self._apply_lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._listeners: list[Listener] = []
        self.last_error: str | None = None

    # --- the background thread ---------------------------------------------------------------------

    def start(self) -> None:
        """Read how far the store is applied, then apply in the background: from the first request on, the lag
        and the backlog are the store's (a store that does not answer yet is read by the thread later)."""
        try:
            if self.leadership.try_acquire():
                with self._apply_lock:
                    self._read_cursor()
            else:
                self.follow()
        except FENCED as refused:
            self._step_down(refused)
        except OUTAGES as error:
            self.last_error = str(error)
        self._thread = threading.Thread(target=self._run, name="segb-applier", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=30)

    def notify(self) -> None:
        """New entries are in the journal."""
        self._wake.set()

    def _run(self) -> None:
        delay = FIRST_RETRY_SECONDS
        while not self._stop.is_set():
            # Also wakes by itself: another process may have appended entries, or applied them (API workers).
            self._wake.wait(timeout=FOLLOW_SECONDS)
            self._wake.clear()
            try:
                self.apply_pending()
            except OUTAGES as error:
                logger.warning("applying the journal failed (%s); retrying in %.1f s", error, delay)
                self._stop.wait(delay)
                delay = min(delay * 2, MAX_RETRY_SECONDS)
                self._wake.set()
                continue
            except Exception:  # never let the thread die: the next entry may apply
                logger.exception("applying the journal failed")
                self._stop.wait(delay)
                continue
            delay = FIRST_RETRY_SECONDS

    # --- applying ------------------------------------------------------------------------------------

    def on_applied(self, listener: Listener) -> None:
        """Call `listener` after each step (from the applying thread), e.g. to keep reports current."""
        self._listeners.append(listener)

    @property
    def applied(self) -> int:
        """The entry the store is known to be applied through (0 until first read)."""
        return self.cursor.value

    def apply_pending(self, *, wait: bool = True) -> int:
        """Apply every entry the journal holds beyond the store's cursor; returns the cursor. Raises
        StoreError when the store fails (nothing is lost: the next call resumes at the cursor). In a process
        that does not lead, only reads how far the leader applied. Without `wait`, returns at once when another
        thread is applying (it applies what was appended meanwhile too, or the applier's thread does)."""
        if not self.leadership.try_acquire():
            return self.follow()
        if not self._apply_lock.acquire(blocking=wait):
            return self.cursor.value
        try:
            self._read_cursor()
            while entries := self.journal.entries_after(self.applied, ENTRIES_PER_READ):
                for step in self._steps(entries):
                    self._apply(step)
        except FENCED as refused:
            self._step_down(refused)
            return self.cursor.value
        except OUTAGES as error:
            self._cursor_read = False  # the store may come back restored or wiped: read its cursor again
            self.last_error = str(error)
            raise
        finally:
            self._apply_lock.release()
        self.last_error = None
        return self.cursor.value

    def wait_for(self, sequence: int, timeout: float) -> bool:
        """Wait until entry `sequence` is applied (True), or `timeout` seconds passed (False). A follower's
        progress is the leader's: it reads the store's cursor while it waits."""
        poll = None if self.leadership.held else self._follow_quietly
        return self.cursor.wait_for(sequence, timeout, poll=poll, poll_seconds=WAIT_POLL_SECONDS)

    def lag(self) -> tuple[int, float]:
        """Entries not applied yet, and how long the oldest of them has waited (seconds)."""
        behind = self.journal.head() - self.applied
        if behind <= 0:
            return 0, 0.0
        return behind, self.journal.age_of(self.applied + 1)

    def follow(self) -> int:
        """Take the store's cursor as this process's progress (it is the leader's); raises the store's outage."""
        cursor = self.store.applied_through()
        # Never backwards: a store behind what was seen applied is one restored or wiped, which the leader
        # brings up again; meanwhile what this process told its posters stays true of the journal.
        if cursor is not None:
            self.cursor.advance(cursor)
        return self.applied

    def _follow_quietly(self) -> None:
        try:
            self.follow()
        except OUTAGES as error:
            self.last_error = str(error)

    def _read_cursor(self) -> None:
        """The leader, under `_apply_lock`: once after start, after each outage and for each new apply epoch, the
        store's own cursor. A new epoch claims the store first: what an older leader still writes is refused from
        then on, so the cursor read is where it stopped for good."""
        epoch = self.leadership.epoch
        if self._cursor_read and epoch == self._epoch:
            return
        if epoch is not None and epoch != self._epoch:
            epoch = self._claim(epoch)
        self._epoch = epoch
        self.cursor.set(self._starting_point())
        self._cursor_read = True

    def _claim(self, epoch: int) -> int:
        """Claim the store for `epoch`, or for a newer one drawn when the store's own epoch was never drawn by this
        state database (restored from an older backup): no leader could ever write otherwise."""
        try:
            self.store.claim(epoch)
            return epoch
        except StoreFenced as refused:
            leadership = self.leadership
            beyond = leadership.draw_beyond(refused.newer) if isinstance(leadership, SharedLeadership) else None
            if beyond is None:
                raise
            logger.warning(
                "the store was written by apply epoch %d, which the state database never drew (restored from an "
                "older backup?): apply epochs go on from %d",
                refused.newer,
                beyond,
            )
        self.store.claim(beyond)
        return beyond

    def _step_down(self, refused: StoreFenced | StateFenced) -> None:
        """A write of this applier's epoch was refused: another process leads with a newer one. Stop applying
        (the step under way is the new leader's to write) and follow it."""
        logger.warning(
            "stopped applying the journal after entry %d: %s; another process leads now, this one follows it",
            self.applied,
            str(refused),  # not the error itself: its traceback would outlive this thread in a handler's records
        )
        self._cursor_read = False
        if self.leadership.epoch == refused.epoch:  # not a lead taken again since, under a newer epoch
            self.leadership.release()

    def _starting_point(self) -> int:
        cursor = self.store.applied_through()
        head = self.journal.head()
        erased = self.journal.last_applied_erasure()
        if cursor is not None and cursor < erased <= head:
            # A store from before an erasure whose removed lines are no longer kept (a backup restored): it is
            # brought up again from the redacted journal, so nothing erased stays in it.
            logger.warning(
                "the store is applied through entry %d, before erasure %d: applying the journal to it anew",
                cursor,
                erased,
            )
            self.store.clear(through=None, epoch=self._epoch)
            cursor = None
        if cursor is None or cursor > head:
            if cursor is not None:
                logger.warning(
                    "the store says it is applied through entry %d but the journal ends at %d: it belongs to "
                    "another journal; applying this journal's entries since its last clearing over it",
                    cursor,
                    head,
                )
            start = self.journal.last_clearing()
            logger.info("applying the journal to the %s store from entry %d", self.store.kind, start + 1)
            return start
        return cursor

    def _steps(self, entries: Sequence[JournalEntry]) -> list[list[JournalEntry]]:
        """Consecutive posts grouped up to `batch_triples` triples; a clearing or an erasure is a step of its own."""
        steps: list[list[JournalEntry]] = []
        current: list[JournalEntry] = []
        size = 0
        for entry in entries:
            if entry.action != "ingest":  # a clearing or an erasure
                steps += [current, [entry]] if current else [[entry]]
                current, size = [], 0
                continue
            lines = entry.content.count(b"\n")
            if current and size + lines > self.batch_triples:
                steps.append(current)
                current, size = [], 0
            current.append(entry)
            size += lines
        if current:
            steps.append(current)
        return steps

    def _apply(self, entries: list[JournalEntry]) -> None:
        through = entries[-1].sequence
        epoch = self._epoch
        if entries[0].action == "delete_all":
            self.store.clear(through=through, epoch=epoch)
            step = Applied(entries, [], cleared=True)
        elif entries[0].action == "erase":
            removed, added = entries[0].removed, entries[0].added
            if added:  # a text with a name redacted, in place of the text: added first, a step the cursor is at
                self.store.apply(list(parse(added, RdfFormat.N_TRIPLES)), through - 1, epoch)
            # Empty once applied: a store restored from before the erasure gets the posts already redacted.
            self.store.remove(list(parse(removed, RdfFormat.N_TRIPLES)) if removed else [], through, epoch)
            self.journal.erasure_applied(through, epoch)
            step = Applied(entries, [], cleared=False, erased=True)
        else:
            quads = quads_of(entries)
            self.store.apply(quads, through, epoch)
            step = Applied(entries, quads, cleared=False)
        self.cursor.advance(through)
        for listener in self._listeners:
            try:
                listener(step)
            except Exception:  # a listener's failure must not stop the store from being kept current
                logger.exception("a listener of applied entries failed")
