"""A server run as a process of its own for the length of a `with` block: started, waited for, stopped."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.cli.test_cli import wait_for


@contextmanager
def running(
    argv: list[str], *, ready: str, env: dict[str, str] | None = None, log: Path | None = None, timeout: float = 60
) -> Iterator[subprocess.Popen[bytes]]:
    """Start `argv`, wait until `ready` (a URL) answers 200, and stop it (SIGTERM) when the block ends. Its
    stderr goes to `log` when given: a pipe nobody reads would stall it once full."""
    with log.open("wb") if log is not None else open(os.devnull, "wb") as output:
        process = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=output)
    try:
        wait_for(ready, timeout=timeout)
        yield process
    finally:
        process.terminate()
        process.wait(timeout=60)
