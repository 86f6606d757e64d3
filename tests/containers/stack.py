"""A clean copy of the repository where the tests run the README's commands against the tests' own daemon."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import time
from pathlib import Path

import httpx

from tests.support.compose import ROOT, read_env_file
from tests.support.docker import DockerDaemon, docker_cli
from tests.support.net import free_port

READY = b'{"ready": true, "virtuoso": true}'


def copy_checkout(directory: Path) -> Path:
    """The files git tracks, as a fresh clone has them, in `directory/segb` (compose's project name)."""
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    target = directory / "segb"
    for name in filter(None, listed.decode().split("\0")):
        source = ROOT / name
        if source.is_file():  # a file deleted in the working tree but not yet in git's index is skipped
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    return target


class Checkout:
    """A copy of the repository and the commands a user types in it, run against `daemon`."""

    def __init__(self, daemon: DockerDaemon, directory: Path) -> None:
        self.daemon = daemon
        self.directory = copy_checkout(directory)
        self.files: tuple[str, ...] = ()  # extra compose files (`-f`), as a user adds docker-compose.postgres.yaml

    def sh(self, *argv: str, check: bool = True, timeout: float = 600) -> subprocess.CompletedProcess[str]:
        """A command as typed in the checkout; `docker` is the tests' CLI, talking to the tests' daemon."""
        command = [docker_cli() or "docker", *argv[1:]] if argv[0] == "docker" else list(argv)
        return self.daemon.run(command, check=check, cwd=self.directory, timeout=timeout)

    def compose(self, *args: str, check: bool = True, timeout: float = 600) -> subprocess.CompletedProcess[str]:
        files = [argument for name in self.files for argument in ("-f", name)]
        return self.sh("docker", "compose", *files, *args, check=check, timeout=timeout)

    # --- .env ----------------------------------------------------------------------------------------

    def configure(self) -> None:
        """`cp .env.example .env`, with free ports on this machine instead of 5000 and 8080."""
        self.sh("cp", ".env.example", ".env")
        self.set_env(API_PORT=str(free_port()), UI_PORT=str(free_port()))

    def set_env(self, **values: str) -> None:
        env = self.directory / ".env"
        text = env.read_text()
        for name, value in values.items():
            text, count = re.subn(rf"^{name}=.*$", f"{name}={value}", text, flags=re.MULTILINE)
            assert count == 1, f"{name} is not in .env"
        env.write_text(text)

    def env(self, name: str) -> str:
        return read_env_file(self.directory / ".env")[name]

    @property
    def api(self) -> str:
        return f"http://localhost:{self.env('API_PORT')}"

    @property
    def ui(self) -> str:
        return f"http://localhost:{self.env('UI_PORT')}"

    # --- the running stack ---------------------------------------------------------------------------

    def containers(self, service: str) -> list[str]:
        return self.compose("ps", "-q", service).stdout.split()

    def logs(self, service: str) -> str:
        return self.compose("logs", "--no-color", service).stdout

    def health(self) -> dict[str, str]:
        """Service → health of its (first) container, as `docker compose ps` shows it."""
        listed = self.compose("ps", "--all", "--format", "json").stdout
        rows = [json.loads(line) for line in listed.splitlines() if line.strip()]
        return {row["Service"]: row.get("Health") or row["State"] for row in rows}

    def curl_ready(self) -> bytes:
        """The tutorial's `curl -s http://localhost:5000/healthz/ready` (on the port chosen in .env)."""
        return subprocess.run(["curl", "-s", f"{self.api}/healthz/ready"], capture_output=True, timeout=30).stdout

    def wait_ready(self, timeout: float = 120) -> None:
        deadline = time.monotonic() + timeout
        while (printed := self.curl_ready()) != READY:
            assert time.monotonic() < deadline, f"not ready after {timeout} s: {printed!r}"
            time.sleep(0.5)

    def wait_status(self, url: str, status: int, timeout: float = 120) -> None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                if httpx.get(url, timeout=5).status_code == status:
                    return
            except httpx.HTTPError:
                pass
            assert time.monotonic() < deadline, f"{url} did not answer {status} within {timeout} s"
            time.sleep(0.5)

    def virtuoso_count(self) -> int:
        """Triples in the events graph, counted by Virtuoso itself (its SQL client, in its container)."""
        graph = self.env("VIRTUOSO_GRAPH_URI")
        query = f"exec=SPARQL SELECT COUNT(*) FROM <{graph}> WHERE {{ ?s ?p ?o }};"
        printed = self.compose(
            "exec", "-T", "virtuoso", "isql", "1111", "dba", self.env("VIRTUOSO_PASSWORD"), "VERBOSE=OFF", query
        ).stdout
        [count] = [line.strip() for line in printed.splitlines() if line.strip().isdigit()]
        return int(count)

    def receipts(self) -> int:
        verified = httpx.get(f"{self.api}/ledger/verify", params={"deep": "true"}, timeout=60).json()
        assert verified["valid"] is True, verified
        return int(verified["receipts"])
