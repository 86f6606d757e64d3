"""Posts that go ahead of an import in a report's upkeep leave the same rows as the journal's order: the report
reads every key a batch touches again from the store, which holds the import and the posts alike. Held here so
that the posts surely go ahead (the conversations report takes the import in only once they were handed to it),
then every report is compared with its query evaluated in full, on both stores."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

from fastapi import FastAPI

from segb_server.backend.api.app import create_app
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.lanes import SMALL_BATCH_TRIPLES
from segb_server.backend.store.base import Store
from tests.api.test_reports_differential import served_equal_evaluated
from tests.conftest import make_settings
from tests.support.histories import EX, ROBOTS, History, send
from tests.support.in_process import InProcess
from tests.support.settle import settle


def test_posts_taken_ahead_of_an_import_leave_the_rows_of_the_journals_order(store: Store, tmp_path: Path) -> None:
    # Answers that never wait for the views: the report is held behind the import until every post is in.
    settings = make_settings(store=store.kind, data_dir=tmp_path / "data", views_max_lag_seconds=0)
    app = create_app(settings, store=store)
    with InProcess(app) as served:
        keeper = app.state.services.writes.keeper
        view = keeper.lanes["reports/conversations"].view
        taken_in, posted = view.update_in_parts, threading.Event()
        ahead: list[int] = []

        def held_until_posted(delta: Delta, through: int, between: Callable[[], int]) -> None:
            assert posted.wait(60)
            taken_in(delta, through, between)

        def recorded(delta: Delta, through: int, taken_ahead: Callable[[Delta, int], None] = view.update_ahead) -> None:
            ahead.append(through)
            taken_ahead(delta, through)

        view.update_in_parts, view.update_ahead = held_until_posted, recorded
        history = History(7)
        send(served.client, history.backlog(1))  # the robots and people first, each view built
        settle(served.client)
        imported = history.backlog(300)
        assert len(imported) > SMALL_BATCH_TRIPLES
        send(served.client, imported)
        handed_out(app)  # the import a batch of its own (a busy keeper would take the posts with it)
        for post in [history.next_post() for _ in range(12)]:
            if post is not None:  # (a clearing would wait for the views)
                send(served.client, post)
        handed_out(app)
        posted.set()
        settle(served.client)
        assert ahead, "no post went ahead of the import"
        served_equal_evaluated(served.client, [{}, {"robot": f"{EX}robot/{ROBOTS[0]}"}], step=0, page=40)


def handed_out(app: FastAPI) -> None:
    """Wait until every post is handed to the views' lanes."""
    writes = app.state.services.writes
    deadline = time.monotonic() + 30
    while writes.backlog() or writes.keeper.progress.dispatched < writes.applied:
        assert time.monotonic() < deadline
        time.sleep(0.01)
