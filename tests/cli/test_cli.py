"""The `segb` command, run as a real process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from pyoxigraph import RdfFormat

from tests.conftest import FIXTURES
from tests.support.graphs import value_triples
from tests.support.net import free_port

pytestmark = pytest.mark.processes  # runs the segb command

SEGB = [sys.executable, "-m", "segb_server.backend.cli"]  # the `segb` command of this interpreter


def segb(*args: str, env: dict[str, str] | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*SEGB, *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=clean_env(env),
        cwd=cwd,
    )


def clean_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    env = {key: value for key, value in os.environ.items() if not key.startswith(("SECRET_KEY", "STORE", "API_"))}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2])
    env.update(extra or {})
    return env


def test_import_then_export_round_trips_the_fixtures(tmp_path: Path) -> None:
    files = [FIXTURES / "sample_two_robots.ttl", FIXTURES / "reference_uc02.ttl"]
    loaded = segb("import", "--data-dir", str(tmp_path), *map(str, files))
    assert loaded.returncode == 0, loaded.stderr
    assert "sample_two_robots.ttl: 799 triples read, 799 new" in loaded.stdout
    assert "reference_uc02.ttl: 627 triples read" in loaded.stdout

    again = segb("import", "--data-dir", str(tmp_path), str(files[0]))
    assert "799 triples read, 0 new" in again.stdout

    out = tmp_path / "out.nt"
    exported = segb("export", "--data-dir", str(tmp_path), "--format", "ntriples", "--output", str(out))
    assert exported.returncode == 0, exported.stderr
    expected = set().union(*(value_triples(path.read_bytes(), RdfFormat.TURTLE) for path in files))
    assert value_triples(out.read_bytes()) == expected


def test_import_reports_bad_files_clearly(tmp_path: Path) -> None:
    broken = tmp_path / "broken.ttl"
    broken.write_text("@prefix ex: <https://ex.org/> .\nex:a ex:b .\n")
    missing = segb("import", "--data-dir", str(tmp_path), str(tmp_path / "nope.ttl"))
    invalid = segb("import", "--data-dir", str(tmp_path / "db"), str(broken))
    assert (missing.returncode, "no such file" in missing.stderr) == (2, True)
    assert invalid.returncode == 2
    assert "Invalid Turtle at line 2" in invalid.stderr


def test_serve_runs_api_and_ui_and_stops_on_sigterm(tmp_path: Path) -> None:
    api_port, ui_port = free_port(), free_port()
    process = subprocess.Popen(
        [*SEGB, "serve", "--data-dir", str(tmp_path)],
        env=clean_env({"API_PORT": str(api_port), "UI_PORT": str(ui_port)}),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        ready = wait_for(f"http://127.0.0.1:{api_port}/healthz/ready")
        assert ready.json() == {"ready": True, "oxigraph": True}
        page = wait_for(f"http://127.0.0.1:{ui_port}/health")
        assert "Ready" in page.text
        assert "Content-Security-Policy" in page.headers
    finally:
        process.send_signal(signal.SIGTERM)
        output, _ = process.communicate(timeout=30)
    assert process.returncode == 0, output
    assert (tmp_path / "oxigraph").is_dir()


def test_flags_override_environment_and_bad_settings_fail_fast(tmp_path: Path) -> None:
    weak = segb("serve", "--data-dir", str(tmp_path), env={"SECRET_KEY": "short"})
    assert weak.returncode == 2
    assert "SECRET_KEY must be at least 32 characters" in weak.stderr

    port = free_port()
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "segb_server.backend.cli",
            "serve",
            "--only",
            "api",
            "--store",
            "memory",
            "--api-port",
            str(port),
        ],
        env=clean_env({"API_PORT": "1", "STORE": "virtuoso"}),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        assert wait_for(f"http://127.0.0.1:{port}/healthz/ready").json() == {"ready": True, "memory": True}
    finally:
        process.terminate()
        process.wait(timeout=30)


def wait_for(url: str, timeout: float = 30) -> httpx.Response:
    deadline = time.monotonic() + timeout
    while True:
        try:
            return httpx.get(url, timeout=2)
        except httpx.HTTPError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
