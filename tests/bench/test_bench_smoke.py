"""The benchmark runs end to end on a tiny profile and writes its report (figures are not asserted)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.processes  # runs the bench

ROOT = Path(__file__).resolve().parents[2]


def test_tiny_profile_writes_a_report_with_measured_figures(tmp_path: Path) -> None:
    output = tmp_path / "performance.md"
    run = subprocess.run(
        [sys.executable, "-m", "bench", "--profile", "tiny", "--no-virtuoso", "--output", str(output)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    report = output.read_text()
    for heading in (
        "### 1. Small posts",
        "### 2. Many robots",
        "### 3. Apply lag at a steady rate",
        "### 4. Cumulative re-publish",
        "### 5. Reports under live ingest",
        "### Memory",
        "### Targets",
    ):
        assert heading in report
    assert "| no-op server (client + HTTP only) |" in report
    assert "| journal append (SQLite) |" in report  # the in-process breakdown of a small post
    # Every report's first page was served from its rows while a robot kept publishing.
    pages = re.findall(r"\| embedded \| 2,000 \| ([\w-]+) \| ([^|]+) \| \d+ \| (\w+) \|", report)
    assert {name for name, _, _ in pages} >= {"conversations", "participants", "robot-states"}, report
    assert {served for _, _, served in pages} == {"rows"}
    # The robot's messages were heard of on the live stream and seen as rows, every time one was checked.
    live = re.search(r"\| embedded \| 2,000 \| \d+ \| [\d.]+ \| [^|]+ \| 0 \| [\d.]+ / [\d.]+ \| (\d+) \| 0 \|", report)
    assert live is not None and int(live.group(1)) > 0, report
    # And in a real page: the robot's conversations open in Chromium showed every post watched.
    in_page = re.search(r"\| embedded \| 2,000 \| (\d+) \| [\d ./]+ \| 0 \| - \|", report)
    assert in_page is not None and int(in_page.group(1)) > 0, report
    # The journal's size, measured: 8 interactions of the example robot are 1,103 triples.
    assert re.search(r"\| embedded \| 8 \| [\d.]+ \| [\d.]+ \| 1103 \|", report)
    assert re.search(r"\| API process, embedded \| 2,000 \| \d+ \|", report)
    # Nothing lost: the embedded store's export holds exactly the distinct triples the robots sent.
    robots = re.search(r"\| embedded \| 24 \|(?: [^|]+ \|){7} (\d+) \| (\d+) \|", report)
    assert robots is not None, report
    assert int(robots.group(1)) == int(robots.group(2)) > 0
    row = re.search(r"\| embedded \| (\d+) \| (\d+) \| ([\d.]+) \|", report)
    assert row is not None, report
    assert int(row.group(2)) == 30 and float(row.group(3)) > 0
    assert "Machine: cpu" in report
