"""`segb serve` keeps the views in a process of their own: the robot's posts reach the reports through it, a views'
process that dies is started again and catches up, readiness says why the views are behind meanwhile, and none
outlives the server, however the server ends."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta
from pathlib import Path

import httpx
import pytest
from semantic_log_generator import SEGBPublisher

from segb_server.backend.services.views.process import NICENESS, STATUS_FILE
from segb_server.examples.receptionist import log_visit, receptionist
from tests.cli.test_cli import SEGB, clean_env, wait_for
from tests.support.net import free_port
from tests.support.processes import end

pytestmark = pytest.mark.processes  # runs `segb serve`, and kills its processes


T0 = datetime(2026, 5, 4, 9, 0, tzinfo=UTC)


def visits(url: str, first: int, count: int) -> set[str]:
    """`count` visits of the receptionist robot from visit `first`, published with the PyPI client as the robot
    does (its whole graph, once); the visitors' messages."""
    logger = receptionist()
    for index in range(first, first + count):
        log_visit(logger, index, T0 + timedelta(minutes=index))
    logger.publish(SEGBPublisher(base_url=url))
    return {f"Hello ARI, this is visit {index}." for index in range(first, first + count)}


@contextmanager
def serving(data: Path, **env: str) -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    port = free_port()
    argv = [*SEGB, "serve", "--only", "api", "--data-dir", str(data), "--api-port", str(port)]
    with (data.parent / "serve.log").open("wb") as log:
        server = subprocess.Popen(argv, env=clean_env(env), stdout=subprocess.DEVNULL, stderr=log)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_for(f"{url}/healthz/live")
        yield server, url
    finally:
        end(server)


def eventually(check: Callable[[], object], timeout: float = 60, every: float = 0.2) -> object:
    """`check()`'s first truthy answer within `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found or time.monotonic() > deadline:
            assert found, f"not within {timeout} s"
            return found
        time.sleep(every)


def views_pid(data: Path) -> int | None:
    try:
        return int(json.loads((data / STATUS_FILE).read_text())["pid"])
    except (FileNotFoundError, ValueError, KeyError):
        return None


def parent_of(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def niceness_of(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[16])


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"  # a zombie has exited; its parent has not read its status yet


def messages(url: str) -> set[str]:
    """The messages the conversations' kept rows hold: none while the views are still being built (the report is
    then evaluated by its query, which would not show that the views' process kept them)."""
    rows = httpx.get(f"{url}/reports/conversations", params={"limit": 1000}, timeout=30).json()
    if rows["served_from"] != "rows":
        return set()
    return {row["text"] for row in rows["rows"]}


def test_the_views_are_kept_by_a_process_of_their_own_and_the_reports_follow_the_robots(tmp_path: Path) -> None:
    data = tmp_path / "data"
    with serving(data) as (server, url):
        pid = int(eventually(lambda: views_pid(data)))  # type: ignore[arg-type]
        assert pid != server.pid and parent_of(pid) == server.pid
        assert niceness_of(pid) == niceness_of(server.pid) + NICENESS  # below the requests' priority
        said = visits(url, 0, 3)
        eventually(lambda: said <= messages(url))
        ready = httpx.get(f"{url}/healthz/ready", timeout=10).json()
        assert ready["ready"] is True and "views_error" not in ready


def test_a_views_process_that_dies_is_started_again_and_catches_up(tmp_path: Path) -> None:
    data = tmp_path / "data"
    with serving(data) as (_server, url):
        first = int(eventually(lambda: views_pid(data)))  # type: ignore[arg-type]
        eventually(lambda: httpx.get(f"{url}/reports/conversations", timeout=10).json()["served_from"] == "rows")
        os.kill(first, signal.SIGKILL)
        # Meanwhile readiness says why the views are behind, and posts are kept and answered, not held for them.
        began = time.monotonic()
        said = visits(url, 10, 2)
        assert time.monotonic() - began < 10
        second = int(eventually(lambda: (pid := views_pid(data)) not in (None, first) and pid))  # type: ignore[arg-type]
        assert alive(second) and not alive(first)
        eventually(lambda: said <= messages(url))
        log = (tmp_path / "serve.log").read_text()
        assert f"the views' process (pid {first}) exited with signal SIGKILL" in log


def test_readiness_tells_that_the_views_process_is_not_running(tmp_path: Path) -> None:
    data = tmp_path / "data"
    with serving(data) as (_server, url):
        first = int(eventually(lambda: views_pid(data)))  # type: ignore[arg-type]
        os.kill(first, signal.SIGSTOP)  # stopped, not dead: only its silence tells
        try:
            said = visits(url, 20, 1)

            def told() -> str | None:
                answer = httpx.get(f"{url}/healthz/ready", timeout=10).json()
                return answer.get("views_error")

            error = str(eventually(told, timeout=40))
            assert "views' process" in error and str(first) in error
        finally:
            os.kill(first, signal.SIGCONT)
        eventually(lambda: said <= messages(url))
        eventually(lambda: "views_error" not in httpx.get(f"{url}/healthz/ready", timeout=10).json())


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGKILL], ids=["stopped", "killed"])
def test_no_views_process_outlives_the_server(tmp_path: Path, how: signal.Signals) -> None:
    """Nor does anything it made outside its data directory: not even a SIGKILL leaves the store's channel behind
    in the temporary directory."""
    data, temporary = tmp_path / "data", tmp_path / "tmp"
    temporary.mkdir()
    with serving(data, TMPDIR=str(temporary)) as (server, _url):
        pid = int(eventually(lambda: views_pid(data)))  # type: ignore[arg-type]
        end(server, how)
    eventually(lambda: not alive(pid), timeout=30)
    assert list(temporary.iterdir()) == []


def test_without_views_process_the_server_keeps_the_views_itself(tmp_path: Path) -> None:
    data = tmp_path / "data"
    with serving(data, VIEWS_PROCESS="false") as (_server, url):
        said = visits(url, 30, 1)
        eventually(lambda: said <= messages(url))
        assert views_pid(data) is None
