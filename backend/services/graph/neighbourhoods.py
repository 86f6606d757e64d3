"""Neighbourhood views (`/graph?focus=…`) kept until a change reaches them.

A neighbourhood depends only on the nodes within its depth of the focus: which of them there are, their rows,
and the links between them. The graph index records, with each journal step, the nodes a step wrote or linked
(`graph_changes`); a kept view is served again while none of the steps since it was drawn wrote a node it
reaches. Under a stream of posts from one robot, the neighbourhoods of the others are then read once, not at
every request. Every process keeps its own views and checks them against the same table, so a process that
follows another's index keeps them too.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

KEPT_VIEWS = 64  # neighbourhoods kept per process, the least recently asked dropped first
# A neighbourhood reaching more nodes is drawn at every request: keeping what it reaches would let a few deep
# requests around hubs hold hundreds of megabytes.
MAX_KEPT_REACH = 20_000


@dataclass(frozen=True)
class _Kept:
    through: int  # the index's journal entry when the view was drawn (or last found current)
    reached: frozenset[int]  # every node within the depth (its id), drawn or not
    view: dict[str, object]


class KeptNeighbourhoods:
    def __init__(self) -> None:
        self._kept: OrderedDict[object, _Kept] = OrderedDict()
        self._lock = threading.Lock()  # requests run in a pool of threads

    def view(
        self,
        connection: Any,
        request: object,
        draw: Callable[[], tuple[dict[str, object], frozenset[int] | None]],
    ) -> dict[str, object]:
        """`request`'s view: kept, or drawn by `draw` (the view, and the nodes it reaches or None when they are
        more than `MAX_KEPT_REACH`) and kept."""
        state = connection.execute("SELECT through, changes_from FROM graph_state").fetchone()
        if state is None:
            return draw()[0]
        through = int(state[0])  # read before the view: a view kept is never older than what it says
        with self._lock:
            kept = self._kept.get(request)
            if kept is not None:
                self._kept.move_to_end(request)
        if kept is not None and _current(connection, kept):
            with self._lock:
                self._kept[request] = _Kept(max(kept.through, through), kept.reached, kept.view)
            return kept.view
        view, reached = draw()
        if reached is None:
            return view
        with self._lock:
            self._kept[request] = _Kept(through, reached, view)
            self._kept.move_to_end(request)
            while len(self._kept) > KEPT_VIEWS:
                self._kept.popitem(last=False)
        return view


def _current(connection: Any, kept: _Kept) -> bool:
    """Whether no step after the kept view wrote a node it reaches. The log starts again at a build or a
    clearing, and drops its oldest steps: a view older than its start is drawn again. The log is read before its
    start: a pruning meanwhile, which could have removed a change, then says so."""
    changed = connection.execute("SELECT DISTINCT node FROM graph_changes WHERE seq > ?", (kept.through,)).fetchall()
    (complete_from,) = connection.execute("SELECT changes_from FROM graph_state").fetchone()
    if complete_from > kept.through:
        return False
    return not any(node in kept.reached for (node,) in changed)
