"""The journal-digests bench: its two layouts tell the same digests new (what is compared does the same work),
and the command prints both, measured."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.journal_digests import LARGE, RECENT, one_table, tiered
from segb_server.backend.state.sqlite import SqliteDatabase

ROOT = Path(__file__).resolve().parents[2]


def test_both_layouts_tell_the_same_digests_new_across_merges(tmp_path: Path) -> None:
    posts = [[os.urandom(16) for _ in range(7)] for _ in range(40)]
    resent = [[*post[:3], os.urandom(16)] for post in posts[::5]]  # old digests with one new: across merges
    counts = {}
    for name, layout in {"one": one_table, "tiered": tiered(merge_at=20)}.items():
        database = SqliteDatabase(tmp_path / f"{name}.sqlite3")
        database.execute(LARGE)
        database.execute(RECENT)
        counts[name] = [layout(database, digests) for digests in posts + resent + posts[:2]]
        database.close()
    assert counts["one"] == counts["tiered"]
    assert counts["one"] == [7] * 40 + [1] * 8 + [0, 0]


@pytest.mark.processes
def test_the_command_prints_each_layout_measured() -> None:
    command = ["bench.journal_digests", "--history", "20000", "--commits", "60", "--rounds", "1", "--merge-at", "1000"]
    run = subprocess.run(
        [sys.executable, "-m", *command],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    rows = [line for line in run.stdout.splitlines() if line.startswith("| one table") or line.startswith("| tiered")]
    assert len(rows) == 2, run.stdout
    assert all(float(row.split("|")[2]) > 0 for row in rows), run.stdout
