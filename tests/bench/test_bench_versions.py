"""The versions bench runs this tree and an earlier commit in turns and prints every run (figures are not
asserted: that both versions ran, each from its own files, is)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from bench.versions import exported, imported_from, main

pytestmark = pytest.mark.processes  # starts servers

ROOT = Path(__file__).resolve().parents[2]


def test_the_earlier_commits_server_imports_its_own_files() -> None:
    with exported("HEAD") as (short, package_root):
        tree = package_root / "segb_server"
        assert (tree / "backend" / "cli.py").is_file() and short
        assert imported_from(package_root).startswith(str(tree))
    assert not package_root.exists()  # removed, and the repository holds nothing of it
    worktrees = subprocess.run(["git", "-C", str(ROOT), "worktree", "list"], capture_output=True, text=True)
    assert str(package_root) not in worktrees.stdout


def test_a_short_run_prints_both_versions_runs_in_turns(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--against", "HEAD", "--rounds", "1", "--seconds", "3", "--views", "off"]) == 0
    out = capsys.readouterr().out
    short = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert f"| | {short} | this tree |" in out, out
    posts = re.search(r"^\| posts/s \| (\d+), (\d+) \(median \d+\) \| (\d+), (\d+) \(median \d+\) \|$", out, re.M)
    assert posts, out
    assert all(int(rate) > 0 for rate in posts.groups()), out  # two runs of each, every one posted
    assert re.search(r"\| posts/s, this tree ÷ \w+ \(medians\) \| \| [\d.]+ \|", out), out
