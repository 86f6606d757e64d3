"""A guard that fails the test run when the suite writes outside temporary directories.

Before the first test it records the working tree (`git status --porcelain --ignored`), every file under
`./data` (where a user's own `segb serve` keeps its store), and the top of the user's home; after the last
test it compares. Caches that `.gitignore` names (`__pycache__`, `.pytest_cache`, …) may appear; nothing else.
The run's HOME points at a temporary directory, so tools that write to the home (Chromium, fontconfig) write
there instead of into the user's.
"""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

ALLOWED_CACHES = ("__pycache__", ".pytest_cache", ".ruff_cache", ".mypy_cache")
HOME_FOLDERS = ("", ".cache", ".config", ".local", ".local/share", ".pki")


@dataclass(frozen=True)
class Snapshot:
    tree: frozenset[str]
    data: frozenset[tuple[str, int, int]]
    home: frozenset[str]


def redirect_home() -> Path:
    """Point HOME (and the XDG folders) of this run and its child processes at a fresh temporary directory;
    returns the user's real home."""
    real = Path(os.environ.get("HOME") or Path.home())
    fake = Path(tempfile.mkdtemp(prefix="segb-test-home-"))
    atexit.register(shutil.rmtree, fake, ignore_errors=True)  # the run's processes have ended by then
    os.environ["HOME"] = str(fake)
    for name in ("XDG_CACHE_HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_STATE_HOME"):
        os.environ.pop(name, None)
    return real


def take(root: Path, home: Path) -> Snapshot:
    return Snapshot(_tree(root, home), _data(root / "data"), _home(home))


def differences(before: Snapshot, after: Snapshot) -> list[str]:
    """What the run wrote where it must not, one line each."""
    problems = [f"working tree: {line}" for line in sorted(after.tree - before.tree) if not _is_cache(line)]
    changed = {path for path, *_ in after.data ^ before.data}
    problems += [f"./data: {path} was written" for path in sorted(changed)]
    problems += [f"home: {path} appeared" for path in sorted(after.home - before.home)]
    return problems


def _tree(root: Path, home: Path) -> frozenset[str]:
    git = shutil.which("git")
    if git is None or not (root / ".git").exists():
        return frozenset()
    listed = subprocess.run(
        [git, "status", "--porcelain", "--ignored", "--untracked-files=all"],
        cwd=root,
        capture_output=True,
        text=True,
        env={**os.environ, "HOME": str(home)},  # the user's git configuration, not the run's empty home
        check=True,
    )
    return frozenset(listed.stdout.splitlines())


def _data(data: Path) -> frozenset[tuple[str, int, int]]:
    if not data.is_dir():
        return frozenset({("(no ./data)", 0, 0)})
    entries = set()
    for path in data.rglob("*"):
        if path.is_file():
            stat = path.stat()
            entries.add((str(path.relative_to(data)), stat.st_size, stat.st_mtime_ns))
    return frozenset(entries)


def _home(home: Path) -> frozenset[str]:
    entries = set()
    for folder in HOME_FOLDERS:
        path = home / folder
        if path.is_dir():
            entries.update(str(child.relative_to(home)) for child in path.iterdir())
    return frozenset(entries)


def _is_cache(porcelain_line: str) -> bool:
    path = porcelain_line[3:]
    parts = Path(path).parts
    return any(part in ALLOWED_CACHES or part.endswith(".egg-info") for part in parts) or path.endswith(".pyc")
