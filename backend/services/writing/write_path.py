"""The write path in one place: journal → applier (the store) → keeper (the views), and who does which.

A post is recorded in the journal (durable, hash-chained); the applier writes the journal into the store in
order; the views' keeper brings every view (the reports' rows, the graph index, …) up to each applied step.
With several API processes, one among all that share the journal applies (`apply_leadership`: a file lock,
or an advisory lock in PostgreSQL when the state is there), and one per data directory keeps the views
(`views_leadership`); the others follow what the leaders did. A process's `Role` says which of these it may
take on: both (one process, or API workers that keep the views themselves), or one side each when `segb serve`
keeps the views in a process of their own (`backend/services/views/process.py`). What the rest of the server needs of
all this is here: wait until a post is applied or viewed, how far behind each stage is, and what is on its way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Protocol

from pyoxigraph import Quad

from segb_server.backend.config import Settings
from segb_server.backend.services.ops.leadership import (
    LOCK_FILE,
    VIEWS_LOCK_FILE,
    Following,
    Lead,
    Leadership,
    SharedLeadership,
)
from segb_server.backend.services.views.keeper import REST_RATIO, KeptView, ViewKeeper
from segb_server.backend.services.views.seen_terms import SEEN_TERMS_FILE, SeenTerms
from segb_server.backend.services.writing.applier import Applied, Applier
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.services.writing.journal_file import journal_path
from segb_server.backend.state.epochs import APPLY_LOCK
from segb_server.backend.state.opening import open_state
from segb_server.backend.store.base import Store


class Role(Enum):
    """What one process does of the write path, each part when it holds that part's leadership."""

    WHOLE = "whole"  # applies the journal and keeps the views: one process, or API workers that take turns
    API = "api"  # applies the journal; follows the views their own process keeps (`segb serve`, VIEWS_PROCESS)
    VIEWS = "views"  # the views' own process: keeps the views; follows what an API process applies


class ViewsElsewhere(Protocol):
    """How the views' own process is, as an API process learns it (`backend/services/views/process.py`)."""

    def down(self) -> str | None:
        """Why that process is not keeping the views just now; None while it runs."""

    def outage(self) -> str | None:
        """The outage its views are retrying (the store or their storage away): every view waits."""

    def error(self) -> str | None:
        """What readiness tells of its views: the outage, or why views set aside are not built."""

    def building_all(self) -> bool:
        """Every view is being built from the store there (at start, or after an erasure)."""


@dataclass(frozen=True)
class Lag:
    """How far the store and the views are behind: entries, and how long the oldest missing one has waited."""

    apply_entries: int
    apply_seconds: float
    views_entries: int
    views_seconds: float


class WritePath:
    @classmethod
    def open(
        cls,
        settings: Settings,
        store: Store,
        views: list[KeptView],
        housekeeping: Callable[[], None] | None = None,
        role: Role = Role.WHOLE,
    ) -> WritePath:
        """The journal of `settings` (SQLite in the data directory, PostgreSQL with STATE_URL, memory with
        STORE=memory), its applier into `store`, and the keeper of `views`; nothing started yet.
        `housekeeping`: run once the views are ready, by the process that keeps them."""
        in_memory = settings.store == "memory"  # nothing of such a server is meant to be written
        journal = Journal(
            open_state(
                settings.state_url,
                None if in_memory else journal_path(settings.data_dir),
                writers="journal",
                sync_full=settings.journal_sync == "full",
            ),
            max_bytes=settings.journal_max_bytes,
        )
        apply_leadership, views_leadership = _leaderships(settings, role, in_memory)
        applier = Applier(journal, store, batch_triples=settings.apply_batch_triples, leadership=apply_leadership)
        keeps = views and role is not Role.API  # an API process whose views have a process of their own reads them
        seen_terms = SeenTerms(None if in_memory else settings.data_dir / SEEN_TERMS_FILE) if keeps else None
        # A rest after each batch lets the next one hold more posts for the same queries, and (in one process) gives
        # the requests their share of the interpreter. The views' own process on the embedded store has neither
        # reason: its batches cost per post, and a rest would leave its core idle (one robot, 2 minutes: 123 posts/s
        # against 114 resting). A remote store's batches are planned whatever their size: they rest there.
        rests = role is not Role.VIEWS or store.remote
        keeper = ViewKeeper(
            store, journal, views, views_leadership, applier, housekeeping, seen_terms=seen_terms,
            rest_ratio=REST_RATIO if rests else 0.0,
        )  # fmt: skip
        if role is not Role.API:  # an API process's keeper only follows: the steps would pile up in its queue
            applier.on_applied(keeper.on_applied)
        return cls(journal, applier, keeper, apply_leadership, views_leadership, role)

    def __init__(
        self,
        journal: Journal,
        applier: Applier,
        keeper: ViewKeeper,
        apply_leadership: Lead,
        views_leadership: Lead,
        role: Role = Role.WHOLE,
    ) -> None:
        self.journal = journal
        self.applier = applier
        self.keeper = keeper
        self.apply_leadership = apply_leadership
        self.views_leadership = views_leadership
        self.role = role
        self.views_elsewhere: ViewsElsewhere | None = None  # Role.API: how the views' own process is

    def start(self) -> None:
        """Start the background work of a serving API: applying the journal and keeping the views current (or,
        where another process leads, following it)."""
        self.apply_leadership.try_acquire()
        self.views_leadership.try_acquire()
        if self.role is not Role.VIEWS:  # the views' process reads the store's cursor as its views need it
            self.applier.start()
        self.keeper.start()

    def close(self) -> None:
        self.applier.stop()
        self.keeper.stop()
        self.journal.close()
        self.apply_leadership.release()
        self.views_leadership.release()

    def on_applied(self, listener: Callable[[Applied], None]) -> None:
        """Call `listener` after each step the applier writes to the store (in its thread)."""
        self.applier.on_applied(listener)

    # --- what posts and readers wait for -------------------------------------------------------------

    @property
    def applied(self) -> int:
        """The journal entry the store is known to be applied through."""
        return self.applier.applied

    def backlog(self) -> int:
        """Journal entries the store has not applied yet."""
        return self.journal.head() - self.applier.applied

    def entries_written(self) -> None:
        """New entries are in the journal: the applier takes them in its own thread."""
        self.applier.notify()

    def apply_now(self, *, wait: bool = True) -> None:
        """Apply what is pending in the calling thread (a post acknowledged once stored applies its own entry
        rather than hand it to the applier's thread and wait: a thread hop less). Raises the store's outage.
        Without `wait`, leaves it to the thread already applying (a long step: an erasure rewriting the store),
        so a post's wait stays bounded by its own timeout."""
        self.applier.apply_pending(wait=wait)

    def wait_applied(self, sequence: int, timeout: float) -> bool:
        return self.applier.wait_for(sequence, timeout)

    def wait_viewed(self, sequence: int, timeout: float) -> bool:
        """Wait until every view includes entry `sequence` (True), or `timeout` seconds passed."""
        return self.keeper.progress.wait_for(sequence, timeout)

    def lag(self) -> Lag:
        apply_entries, apply_seconds = self.applier.lag()
        views_entries, views_seconds = self.keeper.progress.lag(self.applier.applied)
        return Lag(apply_entries, apply_seconds, views_entries, views_seconds)

    def view_lag(self, view: str | None) -> Lag:
        """How far the store and view `view` (every view, for None) are behind the journal: each view advances at
        its own pace."""
        apply_entries, apply_seconds = self.applier.lag()
        if view is None or view not in self.keeper.lanes:
            return self.lag()
        views_entries, views_seconds = self.keeper.progress.lag(self.applier.applied, view)
        return Lag(apply_entries, apply_seconds, views_entries, views_seconds)

    def view_lags(self) -> dict[str, tuple[int, float]]:
        """Each view behind the store: entries it misses, and how long the oldest of them has waited."""
        return self.keeper.progress.view_lags(self.applier.applied)

    def views_behind(self) -> int:
        """Entries the store has and the views do not (read in memory; 0 before the views are first ready)."""
        return self.keeper.progress.behind(self.applier.applied)

    def views_lag_seconds(self) -> float:
        """How long the oldest entry the views miss has waited (reads the journal; 0 when they miss none)."""
        return self.keeper.progress.lag(self.applier.applied)[1]

    def views_failing(self) -> bool:
        """The views' keeper is retrying an outage (a store away, the views' storage failing), or the views'
        process is not running: every view waits (not so for a view set aside, built again while the others are
        kept current)."""
        elsewhere = self.views_elsewhere
        return self.keeper.outage is not None or (
            elsewhere is not None and (elsewhere.down() is not None or elsewhere.outage() is not None)
        )

    def views_building_all(self) -> bool:
        """Every view is being built from the store (at start, or again after an erasure), here or in the views'
        own process: how far behind they are is that build's doing, not posts outpacing their upkeep."""
        elsewhere = self.views_elsewhere
        return self.keeper.building_all or (elsewhere is not None and elsewhere.building_all())

    def views_error(self) -> str | None:
        """The error the views' keeper is retrying, if it is: an outage, or why views set aside are not built;
        or why the views' process is not keeping them."""
        elsewhere = self.views_elsewhere
        if elsewhere is not None and (why := elsewhere.down() or elsewhere.error()):
            return why
        return self.keeper.last_error

    def building_views(self) -> list[str]:
        """The views being built while the store holds entries they miss (see `ViewKeeper.building`)."""
        return self.keeper.progress.building(self.applier.applied)

    def on_the_way(self, limit: int, view: str | None = None) -> list[Quad] | None:
        """The triples the store has and the views (or `view`) do not have yet (a reader adds them to what a view
        holds to answer as the store would); None when they cannot stand in for the store (a clearing among them,
        or more than `limit` entries)."""
        return self.keeper.progress.pending(self.applier.applied, limit, view if view in self.keeper.lanes else None)


def _leaderships(settings: Settings, role: Role, in_memory: bool) -> tuple[Lead, Lead]:
    """Who applies and who keeps the views, for a process of `role`. A process that does both holds one file
    lock for both; where the views have a process of their own, the API process applies under that lock and the
    views' process holds a lock of its own (so two of them never write the views at once)."""
    if role is Role.VIEWS:
        return Following("the API process"), Leadership(settings.data_dir / VIEWS_LOCK_FILE, "keeps the views current")
    leader = Leadership(None if in_memory else settings.data_dir / LOCK_FILE)
    apply = SharedLeadership(settings.state_url, APPLY_LOCK) if settings.state_url else leader
    if role is Role.API:
        if not settings.state_url:
            leader.doing = "applies the journal"
        return apply, Following("the views' process")
    return apply, leader
