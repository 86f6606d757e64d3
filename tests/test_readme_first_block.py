"""The README's first block, as a newcomer on Debian runs it: a virtual environment is made and entered before
anything is installed (Debian's own Python refuses `pip install` outside one: PEP 668, "externally managed")."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
VENV = re.compile(r"python3 -m venv (\S+) && \. \1/bin/activate")


def first_block() -> list[str]:
    """The commands of the README's first code block (its comments and blank lines left out)."""
    found = re.search(r"^```(\w*)\n(.*?)^```", README, re.MULTILINE | re.DOTALL)
    assert found and found.group(1) == "sh", "the README opens with a block of shell commands"
    lines = (line.strip() for line in found.group(2).splitlines())
    return [line for line in lines if line and not line.startswith("#")]


def test_the_first_block_enters_a_virtual_environment_before_any_install() -> None:
    commands = first_block()
    installs = [index for index, command in enumerate(commands) if "pip install" in command]
    entered = [index for index, command in enumerate(commands) if VENV.search(command)]
    assert installs, commands
    assert entered and entered[0] < installs[0], commands
    assert "python3-venv" in README.split("## Contents", 1)[0]  # the Debian package that gives `python3 -m venv`


@pytest.mark.processes  # runs the block's first command
def test_the_first_block_virtual_environment_command_works_as_written(tmp_path: Path) -> None:
    command = next(command for command in first_block() if VENV.search(command))
    script = f"{command} && python3 -c 'import sys; print(sys.prefix)' && python3 -m pip --version"
    done = subprocess.run(["bash", "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    folder = VENV.search(command)
    assert folder is not None
    prefix = Path(done.stdout.splitlines()[0])
    assert prefix == (tmp_path / folder.group(1)).resolve()  # the block's pip is the environment's
