"""What the keeper asks of a view: `KeptView`, and `ForgetsErased` for a view that keeps, past a clearing, what an
erasure must remove."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

from segb_server.backend.services.views.delta import Delta


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


@runtime_checkable
class GoesAhead(Protocol):
    """A view whose update reads every key a batch touches again from the store, which holds every batch applied:
    its rows are the same whichever order it takes batches in. A post's batch may then be taken before a large
    import queued ahead of it, so the post's rows need not wait for the import's (the view's position, what
    `stored_through` and its lag say, moves only once the import is taken in too)."""

    def update_ahead(self, delta: Delta, through: int) -> None:
        """`update` for a batch taken before an earlier one: its rows, not the view's position."""

    def update_in_parts(self, delta: Delta, through: int, between: Callable[[], int]) -> None:
        """`update`, its keys written a part at a time, calling `between()` before each part and after the last
        (where batches queued behind go ahead); it answers the last entry taken ahead so far, which the view then
        includes too."""
