"""`segb serve` stopped by SIGTERM, as a service manager or `docker stop` stops it: the views' process is asked to
stop and stops, with no word of a kill; the process's start and end are logged once, though it runs two servers."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import httpx
import pytest

from segb_server.backend.services.views.process import STOP_SECONDS
from tests.cli.test_cli import SEGB, clean_env, wait_for
from tests.cli.test_views_process import alive, eventually, views_pid
from tests.support.net import free_port
from tests.support.processes import end

pytestmark = pytest.mark.processes  # runs `segb serve` and signals it

STARTING_SECONDS = 180  # the server, then its views' process, starting and building every view on a busy machine


def test_sigterm_stops_the_views_process_without_killing_it_and_logs_the_process_once(tmp_path: Path) -> None:
    data, log = tmp_path / "data", tmp_path / "serve.log"
    api, ui = free_port(), free_port()
    argv = [*SEGB, "serve", "--data-dir", str(data), "--api-port", str(api), "--ui-port", str(ui)]
    with log.open("wb") as output:
        server = subprocess.Popen(argv, env=clean_env(), stdout=subprocess.DEVNULL, stderr=output)
    try:
        wait_for(f"http://127.0.0.1:{api}/healthz/live", timeout=STARTING_SECONDS)
        views = int(eventually(lambda: views_pid(data), timeout=STARTING_SECONDS))  # type: ignore[arg-type]
        assert wait_for(f"http://127.0.0.1:{ui}/reports", timeout=STARTING_SECONDS).status_code == 200
        # The views built and idle, as when an operator stops a quiet server.
        eventually(
            lambda: (
                httpx.get(f"http://127.0.0.1:{api}/reports/participants", timeout=30).json()["served_from"] == "rows"
            ),
            timeout=STARTING_SECONDS,
        )

        asked = time.monotonic()
        server.send_signal(signal.SIGTERM)
        code = server.wait(timeout=STOP_SECONDS + 30)
        took = time.monotonic() - asked
    finally:
        end(server)
    printed = log.read_text(encoding="utf-8", errors="replace")
    assert code == 0, printed
    assert took < STOP_SECONDS, printed  # an idle views' process finishes at once: nobody waited for a kill
    assert "did not stop" not in printed and "killed" not in printed, printed
    assert not alive(views)
    assert printed.count("Started server process") == 1, printed
    assert printed.count("Finished server process") == 1, printed
