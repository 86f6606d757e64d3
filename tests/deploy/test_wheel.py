"""A plain (non-editable) install serves every page: the wheel, in a new virtual environment, run from an
empty directory, as a user who `pip install`s a release would."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import venv
from pathlib import Path

import httpx
import pytest

from tests.cli.test_cli import wait_for
from tests.cli.test_demo import REPORTS
from tests.support.compose import ROOT
from tests.support.net import free_port

pytestmark = pytest.mark.processes  # builds and installs a wheel, runs what it installed


def checkout_files() -> list[str]:
    """The files a clean checkout of this working tree holds (tracked or new, never ignored ones)."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    return [name for name in listed.stdout.splitlines() if (ROOT / name).is_file()]


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The `bin/` of a fresh virtual environment holding the locked dependencies and the wheel, nothing else."""
    work = tmp_path_factory.mktemp("wheel")
    source = work / "src"
    for name in checkout_files():  # a clean checkout: no build/ or caches of the working tree go in
        target = source / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(work / "dist"), str(source)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert built.returncode == 0, built.stderr
    (wheel,) = (work / "dist").glob("*.whl")
    venv.create(work / "venv", with_pip=True)
    pip = [str(work / "venv" / "bin" / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    for arguments in (["--require-hashes", "-r", str(ROOT / "requirements.lock")], ["--no-deps", str(wheel)]):
        done = subprocess.run([*pip, *arguments], capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr
    return work / "venv" / "bin"


def test_the_wheel_serves_every_report_the_graph_and_the_ui_from_an_empty_directory(
    installed: Path, tmp_path: Path
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    api_port, ui_port = free_port(), free_port()
    environment = {"PATH": f"{installed}:/usr/bin:/bin", "HOME": str(tmp_path), "LANG": "C.UTF-8"}
    process = subprocess.Popen(
        [str(installed / "segb"), "serve", "--demo", "--api-port", str(api_port), "--ui-port", str(ui_port)],
        cwd=empty,
        env=environment,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    api, ui = f"http://127.0.0.1:{api_port}", f"http://127.0.0.1:{ui_port}"
    try:
        wait_for(f"{api}/healthz/ready", timeout=120)
        listed = httpx.get(f"{api}/reports", timeout=30).json()["reports"]
        assert sorted(report["name"] for report in listed) == sorted(REPORTS)
        for name in REPORTS:
            answer = httpx.get(f"{api}/reports/{name}", timeout=30)
            assert answer.status_code == 200 and answer.json()["rows"], f"{name}: {answer.text[:200]}"
        graph = httpx.get(f"{api}/graph", timeout=30).json()
        assert len(graph["nodes"]) > 50 and graph["edges"]
        message = next(node["id"] for node in graph["nodes"] if node["kind"] == "message")
        story = httpx.get(f"{api}/explain", params={"iri": message}, timeout=30)
        assert story.status_code == 200 and story.json()["steps"]
        reports_page = wait_for(f"{ui}/reports")
        assert all(name in reports_page.text for name in ("Maria", "Carlos", "ARI", "TIAGo"))
        graph_page = httpx.get(f"{ui}/kg-graph", timeout=30)
        assert graph_page.status_code == 200 and "cytoscape" in graph_page.text
    finally:
        process.send_signal(signal.SIGTERM)
        log, _ = process.communicate(timeout=60)
    assert process.returncode == 0, log
    assert (empty / "data").is_dir()  # the store went where the user ran it, not into site-packages


def test_the_wheel_fails_loudly_without_its_queries(installed: Path, tmp_path: Path) -> None:
    environment = {"PATH": f"{installed}:/usr/bin:/bin", "HOME": str(tmp_path), "SPARQL_DIR": str(tmp_path)}
    result = subprocess.run(
        [str(installed / "segb"), "serve", "--store", "memory", "--api-port", str(free_port()), "--only", "api"],
        cwd=tmp_path,
        env=environment,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert f"No SPARQL queries (.rq files) in {tmp_path}" in result.stderr
