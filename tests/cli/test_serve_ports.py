"""`segb serve` on a port that is taken says so in one line — which port, and how to choose another — and exits
with 2 before anything starts (it printed uvicorn's bind error and two tracebacks, and exited with 3)."""

from __future__ import annotations

import socket
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from segb_server.backend.cli import main
from tests.cli.test_cli import SEGB, clean_env
from tests.support.net import free_port


@contextmanager
def taken_port() -> Iterator[int]:
    """A loopback port another program listens on."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        yield holder.getsockname()[1]


@pytest.mark.parametrize(("flag", "setting"), [("--api-port", "API_PORT"), ("--ui-port", "UI_PORT")])
def test_a_taken_port_is_one_line_naming_it_and_how_to_choose_another(
    flag: str, setting: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = "--ui-port" if flag == "--api-port" else "--api-port"
    with taken_port() as port:
        code = main(
            ["serve", "--store", "memory", "--data-dir", str(tmp_path), flag, str(port), other, str(free_port())]
        )
    error = capsys.readouterr().err
    assert code == 2
    assert error.splitlines() == [error.strip()], error  # one line, and no traceback
    assert f"port {port} is already in use" in error and flag in error and setting in error
    assert not any(tmp_path.iterdir())  # nothing was started: no store, no journal


@pytest.mark.processes
def test_segb_serve_on_a_taken_port_prints_one_line_and_exits_with_2(tmp_path: Path) -> None:
    with taken_port() as port:
        ran = subprocess.run(
            [*SEGB, "serve", "--only", "api", "--data-dir", str(tmp_path), "--api-port", str(port)],
            capture_output=True,
            text=True,
            timeout=120,
            env=clean_env(),
        )
    assert ran.returncode == 2, ran.stderr
    assert ran.stderr.splitlines() == [
        f"segb: error: the API's port {port} is already in use (127.0.0.1:{port}): stop what holds it, or choose "
        "another port with --api-port or API_PORT"
    ]
