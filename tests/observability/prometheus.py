"""A real Prometheus (Debian's `prometheus` package) on a free loopback port, with a throwaway configuration and
data directory, scraping one target every second; its HTTP query API read back."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import httpx

from tests.support.net import free_port
from tests.support.processes import end

INSTALL_HINT = "install Debian's prometheus package (scripts/test.sh does)"
CONFIG = """\
global:
  scrape_interval: 1s
  scrape_timeout: 1s
scrape_configs:
  - job_name: segb
    metrics_path: /metrics
    authorization:
      credentials: {token}
    static_configs:
      - targets: ["{target}"]
"""


class PrometheusProcess:
    def __init__(self, target: str, token: str) -> None:
        binary = shutil.which("prometheus")
        if binary is None:
            raise RuntimeError(f"prometheus not found: {INSTALL_HINT}")
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.directory = Path(tempfile.mkdtemp(prefix="segb-prometheus-"))
        config = self.directory / "prometheus.yml"
        config.write_text(CONFIG.format(token=token, target=target))
        self.argv = [
            binary,
            f"--config.file={config}",
            f"--storage.tsdb.path={self.directory / 'data'}",
            f"--web.listen-address=127.0.0.1:{self.port}",
            "--log.level=warn",
        ]
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        with (self.directory / "prometheus.log").open("wb") as log:
            self.process = subprocess.Popen(self.argv, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 30
        while True:
            try:
                if httpx.get(f"{self.url}/-/ready", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"prometheus did not start: {(self.directory / 'prometheus.log').read_text()}")
            time.sleep(0.2)

    def stop(self) -> None:
        if self.process is not None:
            end(self.process)
        shutil.rmtree(self.directory, ignore_errors=True)

    def query(self, expression: str) -> list[dict[str, object]]:
        """The instant vector `expression` gives now (Prometheus's /api/v1/query)."""
        answer = httpx.get(f"{self.url}/api/v1/query", params={"query": expression}, timeout=10)
        answer.raise_for_status()
        body = answer.json()
        assert body["status"] == "success", body
        return body["data"]["result"]

    def value_when(self, expression: str, wanted: float, timeout: float = 30) -> float:
        """The value of a one-series `expression` once it reaches `wanted` (scrapes come every second)."""
        deadline = time.monotonic() + timeout
        seen: float | None = None
        while time.monotonic() < deadline:
            result = self.query(expression)
            if result:
                seen = float(result[0]["value"][1])  # type: ignore[index]
                if seen >= wanted:
                    return seen
            time.sleep(0.5)
        raise AssertionError(f"{expression} stayed at {seen}, not {wanted}, for {timeout} s")

    def targets_up(self) -> list[dict[str, object]]:
        answer = httpx.get(f"{self.url}/api/v1/targets", timeout=10).json()
        return answer["data"]["activeTargets"]
