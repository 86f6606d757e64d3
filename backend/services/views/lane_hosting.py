"""What a view's lane asks of the keeper (`lanes.LaneHost`): its turn, a batch's triples read back from the journal,
what to do when its update fails (retry an outage, else set the view aside), when a view set aside is built
again, and telling that it moved."""

from __future__ import annotations

import logging
import threading
import time

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.lanes import Batch, ViewLane
from segb_server.backend.services.views.preparing import ViewBuilds
from segb_server.backend.services.views.progress import ViewsProgress
from segb_server.backend.services.views.turns import Turns
from segb_server.backend.services.writing.applier import applied_steps
from segb_server.backend.services.writing.journal import Journal

logger = logging.getLogger("segb.views")


class LaneHosting:
    def __init__(
        self, journal: Journal, builds: ViewBuilds, progress: ViewsProgress, turns: Turns, stopping: threading.Event
    ) -> None:
        self.journal = journal
        self.builds = builds
        self.progress = progress
        self.turns = turns
        self.stopping = stopping

    def read_back(self, batch: Batch) -> Delta:
        """A batch handed out without its triples, read back from the journal."""
        steps = applied_steps(self.journal.entries_after(batch.first - 1, batch.through - batch.first + 1))
        return Delta.of([quad for step in steps for quad in step.quads], batch.fresh)

    def lane_failed(self, lane: ViewLane, error: BaseException) -> bool:
        """A lane's update failed: True to try it again (the store or the views' storage away), else the view
        is set aside, built again later."""
        try:
            self.builds.set_aside_unless_away(lane.view, error)
        except OUTAGES as outage:
            lane.outage = str(outage)
            logger.warning("keeping view %s current failed (%s); retrying", lane.name, outage)
            return True
        lane.outage = None
        return False

    def is_set_aside(self, lane: ViewLane) -> bool:
        return self.builds.is_set_aside(lane.view)

    def rebuild_due(self, lane: ViewLane) -> int | None:
        """Where a view set aside is built through, once its retry is due (None before)."""
        return self.progress.dispatched if time.monotonic() >= self.builds.retry_at else None

    def rebuild(self, lane: ViewLane, through: int) -> None:
        try:
            self.builds.build_or_set_aside(lane.view, through)
        except OUTAGES as outage:  # the store away: the next turn tries again
            self.builds.set_view_aside(lane.view, outage)
            return
        if not self.builds.is_set_aside(lane.view):
            lane.cursor.advance(through)

    def lane_advanced(self) -> None:
        self.progress.advanced()
