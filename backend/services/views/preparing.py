"""Building the views and catching them up, and the views set aside because their build or update failed on its
own (a bug, a query the store refused): those are built again every `RETRY_BUILD_SECONDS` while the others are
kept current, and readiness tells why they are not."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.seen_terms import SeenTerms
from segb_server.backend.services.views.view import ForgetsErased, KeptView
from segb_server.backend.services.writing.applier import quads_of
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.state.database import StateUnavailable
from segb_server.backend.store.base import Store, StoreUnavailable

logger = logging.getLogger("segb.views")

# A view whose build failed on its own (its query refused by the store, a bug) is set aside and built again
# this often; the others are kept current meanwhile, and its report is evaluated in full.
RETRY_BUILD_SECONDS = 2.0


class ViewBuilds:
    """Builds and catch-ups of the views over one store and journal, and which views are set aside."""

    def __init__(self, store: Store, journal: Journal, seen_terms: SeenTerms | None) -> None:
        self.store = store
        self.journal = journal
        self.seen_terms = seen_terms
        # view → the error its last build failed with. Written by the keeper's threads, read by requests
        # (readiness): replaced, never changed in place, so a reader always holds a whole one.
        self._set_aside: dict[str, str] = {}
        self.retry_at = 0.0  # when the views set aside are built again (time.monotonic())

    # --- set aside ------------------------------------------------------------------------------------

    def is_set_aside(self, view: KeptView) -> bool:
        return view.name in self._set_aside

    @property
    def any_set_aside(self) -> bool:
        return bool(self._set_aside)

    def errors(self) -> str | None:
        """Why the views set aside are not built (None when none is)."""
        return "; ".join(self._set_aside.values()) or None  # one dict read: a whole one

    def set_aside_unless_away(self, view: KeptView, error: BaseException) -> None:
        """Set `view` aside for `error`, or raise it when the store or the views' storage is away (every view
        waits for them, tried again as a whole). A store that answers a ping was not away: the view's query
        failed on its own (e.g. it ran past the store's time limit)."""
        if isinstance(error, StateUnavailable) or (isinstance(error, StoreUnavailable) and not self._store_answers()):
            raise error
        self.set_view_aside(view, error)

    def set_view_aside(self, view: KeptView, error: BaseException) -> None:
        if isinstance(error, OUTAGES):
            logger.warning("view %s failed (%s); set aside, built again in %g s", view.name, error, RETRY_BUILD_SECONDS)
        else:
            logger.error(
                "view %s failed; set aside, built again in %g s", view.name, RETRY_BUILD_SECONDS, exc_info=error
            )
        view.ready = False
        self._set_aside = {**self._set_aside, view.name: f"{view.name}: {error}"}
        self.retry_at = time.monotonic() + RETRY_BUILD_SECONDS

    def put_back(self, view: KeptView) -> None:
        """`view` is built or caught up: it answers from now on (and is no longer set aside)."""
        if view.name in self._set_aside:
            self._set_aside = {name: error for name, error in self._set_aside.items() if name != view.name}
        view.prepared()
        view.ready = True

    def _store_answers(self) -> bool:
        try:
            self.store.ping()
        except Exception:
            return False
        return True

    # --- building -------------------------------------------------------------------------------------

    def build_or_set_aside(self, view: KeptView, through: int) -> None:
        """Build `view` through `through` (raising the store's outage), or set it aside when it fails on its
        own."""
        try:
            build(view, through)
        except Exception as error:
            self.set_aside_unless_away(view, error)
            return
        self.put_back(view)

    def build_all(self, views: list[KeptView], through: int) -> None:
        """Every view built again through `through` (after a failure outside any one view's update)."""
        if self.seen_terms is not None:
            self.seen_terms.build(self.store, through)
        for view in views:
            self.build_or_set_aside(view, through)

    def rebuild_all(self, views: list[KeptView], erased_at: int) -> int:
        """After an erasure: every view emptied, then built from the store (which holds at least the journal
        through `erased_at`); until a view is built again its answers are not served (reports are evaluated by
        their queries meanwhile), so nothing erased is served from old rows. Returns where the views now are."""
        current = max(erased_at, self.store.applied_through() or 0)
        if self.seen_terms is not None:  # the erased IRIs' hashes go too
            self.seen_terms.build(self.store, current)
        for view in views:
            view.ready = False
            view.clear(erased_at)
        for view in views:  # what a clearing keeps (tables of terms, change logs) goes too
            if isinstance(view, ForgetsErased):
                view.forget_erased()
        for view in views:
            self.build_or_set_aside(view, current)
        return current

    def prepare_all(self, views: list[KeptView], advance: Callable[[KeptView, int], None]) -> int:
        """Build each view never built (or of another version) and catch up the others, through the entry the
        store holds now (returned; `advance(view, through)` for each prepared). A view failing on its own (a bug,
        its query refused) is set aside, built again later, and the next ones prepared all the same: one view
        holding the others back would leave every report behind for good. A store away stops them all (tried
        again as a whole)."""
        current = self.store.applied_through() or 0
        if self.seen_terms is not None:
            self._prepare_seen_terms(self.seen_terms, current)
        for view in views:
            if view.ready and view.stored_through() == current:
                continue  # prepared by an earlier try, which the store's outage ended
            try:
                self._prepare(view, current)
            except Exception as error:  # this view's own (its query refused or too slow, a bug), or an outage
                self.set_aside_unless_away(view, error)
                continue
            self.put_back(view)
            advance(view, current)
        return current

    def _prepare(self, view: KeptView, current: int) -> None:
        stored = view.stored_through()
        if stored is None:
            build(view, current)
            return
        try:
            self._catch_up(view, stored, current)
        except OUTAGES:
            raise
        except Exception:  # the thread must live on, and the view be current
            logger.exception("catching view %s up failed; building it again", view.name)
            build(view, current)

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

    def _catch_up(self, view: KeptView, stored: int, current: int) -> None:
        """Apply what the store received while this server was not keeping the view current."""
        if stored >= current:
            return
        started = time.perf_counter()
        entries = self.journal.entries_after(stored, current - stored)
        if any(entry.action != "ingest" for entry in entries):  # a clearing or an erasure
            build(view, current)
            return
        view.update(Delta.of(quads_of(entries)), current)
        logger.info("view %s caught up from entry %d to %d in %.1f s", view.name, stored, current,
                    time.perf_counter() - started)  # fmt: skip


def build(view: KeptView, through: int) -> None:
    started = time.perf_counter()
    view.build(through)
    logger.info("view %s built in %.1f s", view.name, time.perf_counter() - started)
