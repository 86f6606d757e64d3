"""The timeline's bench runs end to end on a small store and writes its own section of the performance page,
leaving the rest of the page as it was; the whole page, written again by `python -m bench`, keeps it."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from bench.report import kept_sections
from bench.timeline import write_section

pytestmark = pytest.mark.processes  # runs the bench command

ROOT = Path(__file__).resolve().parents[2]


def test_the_timeline_bench_writes_its_section_and_keeps_the_rest(tmp_path: Path) -> None:
    output = tmp_path / "performance.md"
    output.write_text("# Performance\n\n### 1. Small posts\n\nkept as it is\n")
    run = subprocess.run(
        [sys.executable, "-m", "bench.timeline", "--size", "20000", "--repeats", "2", "--output", str(output)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    page = output.read_text()
    assert page.startswith("# Performance\n\n### 1. Small posts\n\nkept as it is\n")
    assert "### 10. The investigator's timeline under live ingest" in page
    first = re.search(r"\| first page \(1,000 events\) \| 2 \| ([\d.]+) \| ([\d.]+) \|", page)
    assert first is not None and float(first.group(1)) > 0, page
    heard = re.search(r"\| a post's 201 to its message on `/timeline/stream` \| (\d+) \|", page)
    assert heard is not None and int(heard.group(1)) > 0, page  # the live robot's messages reached the stream
    assert re.search(r"\| every kind kept \| \d+ \| \d+ \| [\d.]+ / [\d.]+ \|", page), page


def test_the_whole_page_keeps_the_sections_other_commands_wrote(tmp_path: Path) -> None:
    page = tmp_path / "performance.md"
    page.write_text("# Performance\n\nold figures\n")
    write_section(page, "<!-- section: timeline -->\nfirst\n<!-- /section: timeline -->")
    write_section(page, "<!-- section: timeline -->\nsecond\n<!-- /section: timeline -->")  # replaced, not added
    assert page.read_text().count("<!-- section: timeline -->") == 1
    assert kept_sections(page) == ["", "<!-- section: timeline -->\nsecond\n<!-- /section: timeline -->"]
