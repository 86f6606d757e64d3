"""`segb serve` stopped by SIGTERM, as a service manager or `docker stop` stops it: the views' process is asked to
stop and stops, with no word of a kill; the process's start and end are logged once, though it runs two servers,
and with --workers each process's start and end say which server it runs."""

from __future__ import annotations

import re
import signal
import subprocess
import time
from pathlib import Path

import httpx
import pytest

from segb_server.backend.services.views.process import STOP_SECONDS
from tests.cli.test_cli import SEGB, clean_env, wait_for
from tests.cli.test_views_process import alive, eventually, views_pid
from tests.deploy.test_generic_store import oxigraph_binary
from tests.support.net import free_port
from tests.support.processes import end, running

pytestmark = pytest.mark.processes  # runs `segb serve` and signals it

STARTING_SECONDS = 180  # the server, then its views' process, starting and building every view on a busy machine


def stopped_by_sigterm(server: subprocess.Popen[bytes]) -> tuple[int, float]:
    """SIGTERM sent: the exit code and the seconds until the process ended."""
    asked = time.monotonic()
    server.send_signal(signal.SIGTERM)
    code = server.wait(timeout=STOP_SECONDS + 30)
    return code, time.monotonic() - asked


def assert_stopped_at_once(code: int, took: float, printed: str) -> None:
    assert code == 0, printed
    assert took < STOP_SECONDS, printed
    assert "did not stop" not in printed and "killed" not in printed, printed


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

        code, took = stopped_by_sigterm(server)
    finally:
        end(server)
    printed = log.read_text(encoding="utf-8", errors="replace")
    assert_stopped_at_once(code, took, printed)  # an idle views' process finishes at once: nobody waited for a kill
    assert not alive(views)
    assert printed.count("Started server process") == 1, printed
    assert printed.count("Finished server process") == 1, printed


def test_sigterm_stops_api_workers_ui_and_views_and_each_process_says_which_server_it_runs(tmp_path: Path) -> None:
    """`--workers 2` on a remote store (Oxigraph's own server) with the views in a process of their own: three
    processes log "Started server process", the UI's and two API workers', each naming its server."""
    binary = oxigraph_binary()
    assert binary, "the oxigraph server is installed from requirements-test.lock"
    store_port, api, ui = free_port(), free_port(), free_port()
    store = f"http://127.0.0.1:{store_port}"
    env = {
        "STORE": "sparql",
        "SPARQL_QUERY_ENDPOINT": f"{store}/query",
        "SPARQL_UPDATE_ENDPOINT": f"{store}/update",
        "VIEWS_PROCESS": "true",
    }
    data, log = tmp_path / "data", tmp_path / "serve.log"
    argv = [*SEGB, "serve", "--workers", "2", "--data-dir", str(data), "--api-port", str(api), "--ui-port", str(ui)]
    store_argv = [binary, "serve", "--location", str(tmp_path / "store"), "--bind", f"127.0.0.1:{store_port}"]
    with running(store_argv, ready=f"{store}/query?query=ASK%7B%7D", timeout=30):
        with log.open("wb") as output:
            server = subprocess.Popen(argv, env=clean_env(env), stdout=subprocess.DEVNULL, stderr=output)
        try:
            wait_for(f"http://127.0.0.1:{api}/healthz/live", timeout=STARTING_SECONDS)
            assert wait_for(f"http://127.0.0.1:{ui}/reports", timeout=STARTING_SECONDS).status_code == 200
            eventually(lambda: views_pid(data), timeout=STARTING_SECONDS)

            code, took = stopped_by_sigterm(server)
        finally:
            end(server)
    printed = log.read_text(encoding="utf-8", errors="replace")
    assert_stopped_at_once(code, took, printed)
    started = re.findall(r"(?:(\w+): )?Started server process \[(\d+)\]", printed)
    finished = re.findall(r"(?:(\w+): )?Finished server process \[(\d+)\]", printed)
    assert sorted(name for name, _ in started) == ["API", "API", "UI"], printed
    assert len({pid for _, pid in started}) == 3, printed  # once per process
    assert sorted(finished) == sorted(started), printed
