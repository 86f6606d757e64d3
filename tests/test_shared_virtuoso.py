"""The suite's watch on the Virtuoso its tests share (tests/support/shared_virtuoso.py), tried in a pytest run of
its own on a real Virtuoso: a test during which Virtuoso stops is run once more on a Virtuoso started again and
passes only if it passes then; a test that stops it every time fails; the tests after either find a store."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

INNER_CONFTEST = """
import pytest
from tests.support.virtuoso import VirtuosoProcess

pytest_plugins = ("tests.support.shared_virtuoso",)


@pytest.fixture(scope="session")
def virtuoso(tmp_path_factory):
    process = VirtuosoProcess(tmp_path_factory.mktemp("virtuoso"))
    process.start()
    yield process
    process.stop()
"""

INNER_TESTS = """
import os
import signal
import time
from pathlib import Path

import httpx
import pytest

STOPPED_ONCE = Path(__file__).with_name("stopped-once")


def stop(virtuoso):
    os.kill(virtuoso.pid, signal.SIGKILL)
    while virtuoso.exit_code() is None:
        time.sleep(0.05)


def answers(virtuoso):
    return httpx.get(f"{virtuoso.base_url}/sparql", params={"query": "ASK {}"}, timeout=10).status_code == 200


@pytest.mark.virtuoso
def test_stops_virtuoso_on_its_first_run_only(virtuoso):
    if not STOPPED_ONCE.exists():
        STOPPED_ONCE.write_text("")
        stop(virtuoso)
        assert answers(virtuoso), "first run: the store went away"
    assert answers(virtuoso)


@pytest.mark.virtuoso
def test_stops_virtuoso_every_time(virtuoso):
    stop(virtuoso)
    assert answers(virtuoso), "every run: the store went away"


@pytest.mark.virtuoso
def test_after_them(virtuoso):
    assert answers(virtuoso)
"""


@pytest.mark.virtuoso
@pytest.mark.processes
def test_a_test_during_which_virtuoso_stops_runs_again_and_passes_only_if_it_passes_then(tmp_path: Path) -> None:
    (tmp_path / "conftest.py").write_text(INNER_CONFTEST)
    (tmp_path / "test_inner.py").write_text(INNER_TESTS)
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    virtuoso: uses the shared Virtuoso\n")
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rA", f"--basetemp={tmp_path / 'base'}"],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=300,
    )
    output = run.stdout + run.stderr
    assert run.returncode == 1, output
    assert re.search(r"PASSED test_inner.py::test_stops_virtuoso_on_its_first_run_only\b", output), output
    assert re.search(r"FAILED test_inner.py::test_stops_virtuoso_every_time\b", output), output
    assert re.search(r"PASSED test_inner.py::test_after_them\b", output), output
    # Each run again is told, with how the first run ended and Virtuoso's own log; the second stop of the test
    # that stops it every time is its failure, told as such.
    assert output.count("the shared Virtuoso stopped; the test was run again") == 2, output
    assert "test_stops_virtuoso_on_its_first_run_only: Virtuoso exited with code -9" in output, output
    assert "first run: the store went away" in output, output
    assert "OpenLink Virtuoso" in output, output  # the end of its log
    assert "every run: the store went away" in output, output
