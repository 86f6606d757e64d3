"""A real Arize Phoenix (PyPI's `arize-phoenix`) receiving OTLP traces, read back through its REST API.

Phoenix brings many dependencies that would fight the project's pins, so it lives in a virtual environment of its
own, installed from its own hashed lock (tests/phoenix/requirements.lock) into the temporary directory, once per
version of that lock (named by its hash, reused by later runs). `phoenix serve` runs on free loopback ports with a
working directory of its own, its telemetry and every download off.
"""

from __future__ import annotations

import atexit
import fcntl
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

from tests.support.net import free_port
from tests.support.processes import end

LOCK = Path(__file__).resolve().parents[1] / "phoenix" / "requirements.lock"
INSTALL_SECONDS = 900


_RUN_CACHE: list[Path] = []


def _cache_root() -> Path:
    """Where Phoenix's virtual environment goes: SEGB_PHOENIX_CACHE when a developer names a folder to keep it in
    between runs; else a temporary folder of this test process, removed when it ends (the machine left as found)."""
    if named := os.environ.get("SEGB_PHOENIX_CACHE"):
        return Path(named)
    if not _RUN_CACHE:
        _RUN_CACHE.append(Path(tempfile.mkdtemp(prefix="segb-phoenix-cache-")))
        atexit.register(shutil.rmtree, _RUN_CACHE[0], ignore_errors=True)
    return _RUN_CACHE[0]


def environment() -> Path:
    """Phoenix's virtual environment, installed from its lock unless this run (or the cache named) has it."""
    digest = hashlib.sha256(LOCK.read_bytes()).hexdigest()[:16]
    root = _cache_root()
    root.mkdir(parents=True, exist_ok=True)
    home = root / f"segb-phoenix-{digest}"
    done = home / "installed"
    with open(f"{home}.lock", "w") as guard:  # another test process may be installing it
        fcntl.flock(guard, fcntl.LOCK_EX)
        if not done.exists():
            shutil.rmtree(home, ignore_errors=True)
            subprocess.run([sys.executable, "-m", "venv", str(home)], check=True)
            subprocess.run(
                [str(home / "bin" / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check",
                 "--require-hashes", "-r", str(LOCK)],
                check=True, timeout=INSTALL_SECONDS,
            )  # fmt: skip
            done.write_text(digest)
    return home


class PhoenixProcess:
    def __init__(self) -> None:
        self.home = environment()
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.directory = Path(tempfile.mkdtemp(prefix="segb-phoenix-run-"))
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        env = {
            **os.environ,
            "PHOENIX_HOST": "127.0.0.1",
            "PHOENIX_PORT": str(self.port),
            "PHOENIX_GRPC_PORT": str(free_port()),
            "PHOENIX_WORKING_DIR": str(self.directory),
            "PHOENIX_TELEMETRY_ENABLED": "false",
            "PHOENIX_ALLOW_EXTERNAL_RESOURCES": "false",
            "PHOENIX_ALLOWED_SANDBOX_PROVIDERS": "NONE",
        }
        log = self.directory / "phoenix.log"
        with log.open("wb") as output:
            self.process = subprocess.Popen(
                [str(self.home / "bin" / "phoenix"), "serve"], env=env, stdout=output, stderr=subprocess.STDOUT,
                cwd=self.directory,
            )  # fmt: skip
        deadline = time.monotonic() + 120
        while True:
            try:
                if httpx.get(f"{self.url}/healthz", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"phoenix did not start: {log.read_text()[-3000:]}")
            time.sleep(0.5)

    def stop(self) -> None:
        if self.process is not None:
            end(self.process)
        shutil.rmtree(self.directory, ignore_errors=True)

    def spans(self, project: str) -> list[dict[str, object]]:
        """Every span Phoenix holds in `project` (none while the project does not exist yet)."""
        found: list[dict[str, object]] = []
        cursor = None
        while True:
            params: dict[str, str | int] = {"limit": 1000, **({"cursor": cursor} if cursor else {})}
            answer = httpx.get(f"{self.url}/v1/projects/{project}/spans", params=params, timeout=30)
            if answer.status_code == 404:
                return found
            answer.raise_for_status()
            body = answer.json()
            found += body["data"]
            cursor = body.get("next_cursor")
            if not cursor:
                return found

    def spans_when(self, project: str, enough: int, timeout: float = 60) -> list[dict[str, object]]:
        deadline = time.monotonic() + timeout
        while True:
            found = self.spans(project)
            if len(found) >= enough or time.monotonic() > deadline:
                return found
            time.sleep(0.5)
