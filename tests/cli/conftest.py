"""Fixtures the command-line tests share."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.test_cli import segb
from tests.conftest import FIXTURES


@pytest.fixture
def data_dir(tmp_path: Path) -> Path:
    """A data directory holding the robot client's sample log (two robots, three people), imported by `segb`."""
    loaded = segb("import", "--data-dir", str(tmp_path), str(FIXTURES / "sample_two_robots.ttl"))
    assert loaded.returncode == 0, loaded.stderr
    return tmp_path
