"""Servers under test, each in its own process so clients and server never share an interpreter."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import IO

import httpx

from bench.measure import peak_rss_mib
from tests.support.net import free_port

ROOT = Path(__file__).resolve().parents[1]


def python_path() -> str:
    """This checkout first, then whatever PYTHONPATH already holds (so a run can point `segb_server` at a
    snapshot of the code rather than the installed package)."""
    return os.pathsep.join(part for part in (str(ROOT), os.environ.get("PYTHONPATH", "")) if part)


class ServerProcess:
    """`with ServerProcess([...argv...], env) as server:` runs until the block ends; `server.url`."""

    def __init__(self, argv: list[str], env: dict[str, str], port: int, ready_path: str = "/healthz/ready") -> None:
        self.url = f"http://127.0.0.1:{port}"
        self._argv = argv
        self._env = {**os.environ, "PYTHONPATH": python_path(), **env}
        self._ready_path = ready_path
        self._process: subprocess.Popen[bytes] | None = None
        self._log: IO[bytes] | None = None
        self.started = 0.0  # time.monotonic() when the process was started
        self.ready_seconds = 0.0  # from start until the ready path answered 200

    def __enter__(self) -> ServerProcess:
        gc.collect()  # between measurements: the bench measures with its collector off (`measure`)
        # The server logs as in production (one line per request); a file, unlike a pipe nobody reads,
        # never fills up and stalls it.
        self._log = log = tempfile.TemporaryFile()
        self.started = time.monotonic()
        self._process = subprocess.Popen(
            [sys.executable, *self._argv], env=self._env, stdout=subprocess.DEVNULL, stderr=log
        )
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                log.seek(0)
                raise RuntimeError(f"server exited: {log.read().decode()[-2000:]}")
            try:
                if httpx.get(self.url + self._ready_path, timeout=2).status_code == 200:
                    self.ready_seconds = time.monotonic() - self.started
                    return self
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        raise RuntimeError(f"server at {self.url} not ready after 120 s")

    def log_text(self) -> str:
        """What the server logged so far (stderr)."""
        if self._log is None:
            return ""
        # pread leaves the file offset alone: the server shares it and keeps appending at it.
        descriptor = self._log.fileno()
        return os.pread(descriptor, os.fstat(descriptor).st_size, 0).decode(errors="replace")

    @property
    def pid(self) -> int | None:
        return self._process.pid if self._process else None

    @property
    def peak_rss_mib(self) -> float | None:
        return peak_rss_mib(self._process.pid) if self._process else None

    def __exit__(self, *exc_info: object) -> None:
        if self._process is not None:
            self._process.terminate()
            try:
                self._process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self._process.kill()
        if self._log is not None:
            self._log.close()


def segb_server(store: str, data_dir: Path, env: dict[str, str] | None = None) -> ServerProcess:
    """The SEGB API (`segb serve --only api`) on a free port, logging at the default level."""
    port = free_port()
    argv = [
        "-m",
        "segb_server.backend.cli",
        "serve",
        "--only",
        "api",
        "--store",
        store,
        "--data-dir",
        str(data_dir),
        "--api-port",
        str(port),
    ]
    return ServerProcess(argv, {"SECRET_KEY": "", "LOGGING_LEVEL": "INFO", **(env or {})}, port)


def baseline_server(endpoint: str, user: str, password: str, graph: str) -> ServerProcess:
    """The naive reference-style server of bench/baseline.py, pointed at the same Virtuoso."""
    port = free_port()
    argv = [
        "-m",
        "bench.baseline",
        "--port",
        str(port),
        "--endpoint",
        endpoint,
        "--user",
        user,
        "--password",
        password,
        "--graph",
        graph,
    ]
    return ServerProcess(argv, {}, port, ready_path="/healthz/live")


def null_server() -> ServerProcess:
    """bench/null_server.py: answers every POST at once, for the client's own share of the latency."""
    port = free_port()
    return ServerProcess(["-m", "bench.null_server", "--port", str(port)], {}, port, ready_path="/healthz/live")


def ui_server(api_url: str) -> ServerProcess:
    """The web UI (`segb serve --only ui`) on a free port, reaching the API at `api_url`."""
    port = free_port()
    argv = ["-m", "segb_server.backend.cli", "serve", "--only", "ui", "--backend-url", api_url, "--ui-port", str(port)]
    return ServerProcess(argv, {"SECRET_KEY": "", "LOGGING_LEVEL": "WARNING"}, port, ready_path="/health")
