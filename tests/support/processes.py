"""Servers run as processes of their own: for the length of a `with` block (started, waited for, stopped), and
stopped with a signal of choice."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def running(
    argv: list[str], *, ready: str, env: dict[str, str] | None = None, log: Path | None = None, timeout: float = 180
) -> Iterator[subprocess.Popen[bytes]]:
    """Start `argv`, wait until `ready` (a URL) answers 200, and stop it (SIGTERM) when the block ends. Its
    stderr goes to `log` when given: a pipe nobody reads would stall it once full."""
    from tests.cli.test_cli import wait_for  # not at the top: that module imports conftest, which imports this one

    with log.open("wb") if log is not None else open(os.devnull, "wb") as output:
        process = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=output)
    try:
        wait_for(ready, timeout=timeout)
        yield process
    finally:
        process.terminate()
        process.wait(timeout=60)


def end(process: subprocess.Popen[bytes], how: signal.Signals = signal.SIGTERM, timeout: float = 30) -> None:
    """Ask `process` to stop with the signal `how`; kill it if it has not within `timeout` seconds."""
    if process.poll() is not None:
        return
    process.send_signal(how)
    try:
        process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
