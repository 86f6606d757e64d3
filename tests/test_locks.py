"""The hashed locks: both pin the same versions, the test lock covers every test tool, and the README's test
command installs from it (so every machine runs the same versions)."""

from __future__ import annotations

import tomllib

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from tests.deploy.test_image import LOCK_ENTRY
from tests.support.compose import ROOT

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def pins(lock: str) -> dict[str, str]:
    entries = LOCK_ENTRY.findall((ROOT / lock).read_text())
    assert entries and all(hashes.count("--hash=") for _, _, hashes in entries), f"{lock}: a pin without hashes"
    return {canonicalize_name(name): version for name, version, _ in entries}


def test_the_run_time_lock_pins_the_same_versions_as_the_test_lock() -> None:
    run_time, test = pins("requirements.lock"), pins("requirements-test.lock")
    assert {name: version for name, version in run_time.items() if test.get(name) != version} == {}


def test_the_test_lock_pins_every_test_tool_within_its_range() -> None:
    test = pins("requirements-test.lock")
    for dependency in PYPROJECT["project"]["optional-dependencies"]["test"]:
        requirement = Requirement(dependency)
        name = canonicalize_name(requirement.name)
        assert name in test, f"{name} is not in requirements-test.lock"
        assert requirement.specifier.contains(test[name], prereleases=True), f"{name}=={test[name]} ≠ {requirement}"


def test_the_test_command_installs_from_the_test_lock_with_hashes() -> None:
    script = (ROOT / "scripts" / "test.sh").read_text()
    assert "--require-hashes -r requirements-test.lock" in script
    assert "--no-deps --no-build-isolation -e ." in script  # setuptools from the lock too
    assert "./scripts/test.sh" in (ROOT / ".ci" / "run").read_text()
