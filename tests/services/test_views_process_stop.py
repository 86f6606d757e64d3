"""Stopping the views' process (`ViewsProcess.stop`, as `segb serve` does on SIGTERM): one that finishes is reaped
with no word of a kill, though the supervising thread reaps it meanwhile (a stop that reaped it too sometimes lost
that race, took the exited process for alive and logged a kill of it at once); one that does not is killed once
STOP_SECONDS have really passed, and the log says so."""

from __future__ import annotations

import logging
import os
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from segb_server.backend.services.views import process as views_process
from segb_server.backend.services.views.process import ViewsProcess, ViewsStatus
from tests.cli.test_views_process import alive, eventually, views_pid
from tests.conftest import make_settings

pytestmark = pytest.mark.processes  # starts the views' process

STARTING_SECONDS = 120  # a spawned interpreter importing the server, on a busy machine


@contextmanager
def running_views(data_dir: Path) -> Iterator[ViewsProcess]:
    """The views' process of an embedded store no API process holds (it opens the store itself), running."""
    settings = make_settings(store="oxigraph", data_dir=data_dir)
    data_dir.mkdir()
    supervisor = ViewsProcess(settings, None)
    supervisor.start()
    try:
        eventually(lambda: views_pid(data_dir) and ViewsStatus(data_dir).down() is None, timeout=STARTING_SECONDS)
        yield supervisor
    finally:
        supervisor.stop()


def test_a_views_process_that_finishes_is_stopped_with_no_word_of_a_kill(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    with running_views(tmp_path / "data") as views:
        running = views.process
        assert running is not None and running.pid is not None
        with caplog.at_level(logging.INFO, logger="segb.views"):
            asked = time.monotonic()
            views.stop()
            took = time.monotonic() - asked
    assert took < views_process.STOP_SECONDS / 2, caplog.text  # an idle views' process ends at once
    assert "did not stop" not in caplog.text and "killed" not in caplog.text
    assert running.exitcode == 0  # it ended by itself, once told to (a kill would say -9)
    assert not alive(running.pid)
    assert views.started == 1  # and was not started again


def test_a_views_process_that_does_not_stop_is_killed_once_the_wait_is_over(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(views_process, "STOP_SECONDS", 2.0)
    with running_views(tmp_path / "data") as views:
        stuck = views.process
        assert stuck is not None and stuck.pid is not None
        os.kill(stuck.pid, signal.SIGSTOP)  # it cannot answer the stop
        with caplog.at_level(logging.WARNING, logger="segb.views"):
            asked = time.monotonic()
            views.stop()
            took = time.monotonic() - asked
    assert f"the views' process (pid {stuck.pid}) did not stop within 2 s; killed" in caplog.text
    assert 2.0 <= took < 2.0 + 10  # the whole wait, then the kill
    assert stuck.exitcode == -signal.SIGKILL
    assert not alive(stuck.pid)
