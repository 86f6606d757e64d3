"""`segb --version`, and `segb check` listing its findings down the file, as a reader of the log goes."""

from __future__ import annotations

import importlib.metadata
import json
import re
from pathlib import Path

import pytest

from tests.cli.test_cli import segb
from tests.support.rule_scenarios import troubled

pytestmark = pytest.mark.processes  # runs the segb command


def test_version_prints_the_installed_version() -> None:
    result = segb("--version")
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"segb {importlib.metadata.version('segb-server')}\n"


@pytest.fixture(scope="module")
def troubled_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A robot's whole log with findings of several rules on lines far apart."""
    scenario, _expected = troubled()
    scenario.run_steps()
    log = tmp_path_factory.mktemp("check") / "ari.ttl"
    log.write_text(scenario.published_turtle()[0], encoding="utf-8")
    return log


def test_check_prints_findings_by_line_then_rule(troubled_log: Path) -> None:
    result = segb("check", str(troubled_log))
    assert result.returncode == 1, result.stderr
    found = [re.match(rf"{re.escape(str(troubled_log))}:(\d+): \w+: \[([\w-]+)\]", line) for line in
             result.stdout.splitlines()[:-1]]  # fmt: skip
    assert all(found), result.stdout
    places = [(int(match.group(1)), match.group(2)) for match in found if match]
    assert len({line for line, _ in places}) > 3  # findings on several lines: the order is worth checking
    assert places == sorted(places)


def test_check_as_json_lists_findings_by_line_then_rule(troubled_log: Path) -> None:
    result = segb("check", str(troubled_log), "--format", "json")
    findings = json.loads(result.stdout)["findings"]
    places = [(found["line"], found["rule"]) for found in findings]
    assert all(line for line, _ in places) and len({line for line, _ in places}) > 3
    assert places == sorted(places)
