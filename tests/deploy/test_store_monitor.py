"""An API started before its Virtuoso retries with backoff, says so in its log, and serves once Virtuoso is up."""

from __future__ import annotations

import re
from pathlib import Path

import httpx
import pytest

from tests.support.compose import NativeProcess, NativeService, host_environment
from tests.support.net import free_port
from tests.support.virtuoso import VirtuosoProcess

pytestmark = pytest.mark.virtuoso

READY = b'{"ready": true, "virtuoso": true}'


def start_api(
    directory: Path, api_port: int, virtuoso_http_port: int, password: str = VirtuosoProcess.password
) -> NativeProcess:
    environment = {
        **host_environment(directory),
        "STORE": "virtuoso",
        "VIRTUOSO_ENDPOINT": f"http://127.0.0.1:{virtuoso_http_port}/sparql-auth",
        "VIRTUOSO_PASSWORD": password,
        "DATA_DIR": str(directory / "data"),
        "STORE_RETRY_MAX_SECONDS": "1",
        "STORE_CHECK_SECONDS": "0.5",
        "LOGGING_LEVEL": "INFO",
    }
    command = ["segb", "serve", "--only", "api", "--api-port", str(api_port)]
    return NativeProcess("api", NativeService(command, environment), cwd=directory, log_dir=directory)


def test_api_retries_until_virtuoso_answers_then_logs_losses_and_returns(tmp_path: Path) -> None:
    api_port, http_port, sql_port = free_port(), free_port(), free_port()
    ready = f"http://127.0.0.1:{api_port}/healthz/ready"
    api = start_api(tmp_path, api_port, http_port)
    (tmp_path / "virtuoso").mkdir()
    virtuoso = VirtuosoProcess(tmp_path / "virtuoso", http_port=http_port, sql_port=sql_port)
    try:
        down = api.wait_for(ready, status=503)
        assert down.json()["ready"] is False and down.json()["virtuoso"] is False
        # 0.5 s, doubled, then capped at STORE_RETRY_MAX_SECONDS=1
        log = api.wait_for_output("store not reachable (virtuoso", count=4, timeout=30)
        delays = re.findall(r"attempt (\d+)\): .*; retrying in ([\d.]+) s", log)
        assert delays[:4] == [("1", "0.5"), ("2", "1.0"), ("3", "1.0"), ("4", "1.0")]
        assert "WARNING segb.store: store not reachable (virtuoso, attempt 1)" in log
        assert "store reachable" not in log

        virtuoso.start()
        assert api.wait_for(ready, timeout=30).content == READY
        api.wait_for_output("INFO segb.store: store reachable (virtuoso)", timeout=10)

        virtuoso.stop()
        log = api.wait_for_output("WARNING segb.store: store lost (virtuoso)", timeout=10)
        assert httpx.get(ready, timeout=5).status_code == 503
        virtuoso.start()
        log = api.wait_for_output("INFO segb.store: store back (virtuoso)", timeout=30)
        assert httpx.get(ready, timeout=5).content == READY
        assert log.count("store reachable") == 1  # announced once; later recoveries say "back"
    finally:
        virtuoso.stop()
        exit_code = api.stop()
    # Shutdown cancels the background check cleanly: a normal exit, no traceback.
    assert exit_code == 0, api.output()[-3000:]
    assert "Traceback" not in api.output()


def test_api_whose_password_virtuoso_refuses_says_why_in_its_log_and_readiness(
    tmp_path: Path, virtuoso: VirtuosoProcess
) -> None:
    """VIRTUOSO_PASSWORD changed after Virtuoso's database was created: an error naming the cause and the way
    out, at every retry, instead of retries that only say "not reachable"."""
    api_port = free_port()
    api = start_api(tmp_path, api_port, virtuoso.http_port, password="changed-after-the-volume-was-made")
    try:
        down = api.wait_for(f"http://127.0.0.1:{api_port}/healthz/ready", status=503).json()
        log = api.wait_for_output("Virtuoso refused the password", count=2, timeout=30)
    finally:
        exit_code = api.stop()
    explanation = (
        "Virtuoso refused the password of user dba (HTTP 401): VIRTUOSO_PASSWORD is not that account's password. "
        "Virtuoso keeps the password its database was created with (in docker compose: when the virtuoso-data "
        "volume was created), so changing VIRTUOSO_PASSWORD later does not change it. Set VIRTUOSO_PASSWORD back "
        "to that password, or change it in Virtuoso (isql: user_set_password('dba', '<new password>'))"
    )
    assert down == {"ready": False, "virtuoso": False, "detail": explanation}
    assert f"ERROR segb.store: store not reachable (virtuoso, attempt 1): {explanation}; retrying in 0.5 s" in log
    assert exit_code == 0 and "Traceback" not in api.output()
