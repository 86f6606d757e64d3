"""The Dockerfile: a hash-pinned lock covering every dependency, every runtime file in the image, a non-root user."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from tests.support.compose import (
    ROOT,
    Instruction,
    dockerfile_stages,
    final_stage,
    image_environment,
    image_healthcheck,
    stage_copies,
)

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
LOCK_ENTRY = re.compile(
    r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;]+)(?: ?;[^\\\n]*)?((?:\s*\\\n\s*--hash=sha256:[0-9a-f]{64})*)", re.MULTILINE
)


def locked() -> dict[str, tuple[str, int]]:
    """Canonical name → (pinned version, number of hashes) for each entry of requirements.lock."""
    text = (ROOT / "requirements.lock").read_text()
    entries = LOCK_ENTRY.findall(text)
    return {canonicalize_name(name): (version, hashes.count("--hash=")) for name, version, hashes in entries}


def build_stage() -> list[Instruction]:
    return dockerfile_stages((ROOT / "Dockerfile").read_text())[0]


def packages() -> list[str]:
    """Top-level folders of the checkout that setup.py installs under `segb_server`."""
    mapped = re.search(r"CODE_FOLDERS = \(([^)]*)\)", (ROOT / "setup.py").read_text())
    assert mapped, "setup.py names its CODE_FOLDERS"
    return sorted([*re.findall(r'"([a-z_]+)"', mapped.group(1)), "sparql", "rules"])


def test_lock_pins_every_runtime_dependency_with_hashes() -> None:
    entries = locked()
    for dependency in PYPROJECT["project"]["dependencies"]:
        requirement = Requirement(dependency)
        name = canonicalize_name(requirement.name)
        assert name in entries, f"{requirement.name} is not in requirements.lock"
        version, hashes = entries[name]
        assert requirement.specifier.contains(version, prereleases=True), f"{name}=={version} ≠ {requirement}"
        assert hashes > 0, f"{name} has no hash"


def test_every_locked_package_has_a_hash_as_require_hashes_demands() -> None:
    entries = locked()
    assert len(entries) > 20
    assert [name for name, (_, hashes) in entries.items() if hashes == 0] == []


def test_build_stage_installs_the_lock_with_hashes_and_copies_every_package() -> None:
    runs = " ".join(i.arguments for i in build_stage() if i.keyword == "RUN")
    assert "--require-hashes -r requirements.lock" in runs
    copied = {source for sources, _ in stage_copies(build_stage()) for source in sources}
    assert {"requirements.lock", "pyproject.toml", "setup.py", "README.md"} <= copied
    assert packages() == ["backend", "examples", "rules", "sparql", "ui"]
    assert set(packages()) <= copied  # `segb demo` and `segb serve --demo` import examples.emotion_mirror


def test_build_stage_builds_the_project_with_the_locked_build_tools_only() -> None:
    """`pip install .` with build isolation would fetch the newest setuptools, unpinned and unchecked: the
    image builds the project with the lock's setuptools instead, and downloads nothing at that step."""
    runs = [i.arguments for i in build_stage() if i.keyword == "RUN"]
    [install] = [run for run in runs if run.endswith(" .")]
    assert "--no-build-isolation" in install and "--no-index" in install
    entries = locked()
    for requirement in map(Requirement, PYPROJECT["build-system"]["requires"]):
        name = canonicalize_name(requirement.name)
        assert name in entries, f"{requirement.name} (pyproject's build-system) is not in requirements.lock"
        version, hashes = entries[name]
        assert requirement.specifier.contains(version) and hashes > 0, f"{name}=={version} ≠ {requirement}"


def test_dockerfile_names_no_frontend_so_buildkit_needs_no_registry() -> None:
    """A `# syntax=` parser directive makes every BuildKit build fetch that frontend image first, which fails
    offline or behind a registry mirror; the built-in frontend reads this Dockerfile."""
    leading = [line for line in (ROOT / "Dockerfile").read_text().splitlines() if line.startswith("#")]
    assert not [line for line in leading if re.match(r"#\s*syntax\s*=", line, re.IGNORECASE)]


def test_final_stage_runs_unprivileged_on_the_same_base_without_build_tools() -> None:
    stage = final_stage()
    assert stage[0].arguments == build_stage()[0].arguments.split(" AS ")[0]  # the venv's Python is the same
    user = [i.arguments for i in stage if i.keyword == "USER"]
    assert user and user[-1] not in ("root", "0")
    runs = " ".join(i.arguments for i in stage if i.keyword == "RUN")
    assert not re.search(r"apt-get|apk |gcc|build-essential|pip install", runs)
    from_build = [i.arguments for i in stage if i.keyword == "COPY" and i.arguments.startswith("--from")]
    assert from_build == ["--from=build /venv /venv"]


def test_final_stage_leaves_the_queries_to_the_installed_package() -> None:
    environment = image_environment(final_stage())
    assert "SPARQL_DIR" not in environment  # the .rq files are package data (segb_server/sparql)
    assert environment["PATH"].startswith("/venv/bin:")
    assert environment["HOST"] == "0.0.0.0"


def test_healthcheck_probes_api_readiness() -> None:
    options, command = image_healthcheck(final_stage())
    assert command[:2] == ["python", "-c"]
    assert "http://127.0.0.1:5000/healthz/ready" in command[2]
    assert {"interval", "timeout", "retries"} <= set(options)


def test_package_built_from_the_build_stage_copies_holds_every_runtime_file(tmp_path: Path) -> None:
    """What `pip install --no-deps .` installs in the image: built from exactly the files the stage copies,
    with the same build tools (the lock's setuptools, no build isolation, nothing downloaded)."""
    source = tmp_path / "src"
    for sources, destination in stage_copies(build_stage()):
        for name in sources:
            # as Docker does: into a directory when the destination ends with "/", else to that name
            into_directory = destination.endswith("/") or destination == "."
            target = source / destination / name if into_directory else source / destination
            if (ROOT / name).is_dir():
                shutil.copytree(ROOT / name, target, ignore=shutil.ignore_patterns("__pycache__"))
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy(ROOT / name, target)
    as_the_image_does = ["--no-deps", "--no-build-isolation", "--no-index"]
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", *as_the_image_does, "-w", str(tmp_path / "wheel"), str(source)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert built.returncode == 0, built.stderr
    (wheel,) = (tmp_path / "wheel").glob("*.whl")
    in_wheel = set(zipfile.ZipFile(wheel).namelist())
    needed = {
        "segb_server/" + path.relative_to(source).as_posix()
        for package in packages()
        for path in (source / package).rglob("*")
        if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".md"
    }
    assert needed - in_wheel == set()
    assert "segb_server/ui/static/vendor/cytoscape/cytoscape.min.js" in in_wheel
    assert "segb_server/sparql/reports/participants.rq" in in_wheel
    assert "segb_server/rules/late-answer.rq" in in_wheel and "segb_server/rules/time-not-datetime.ttl" in in_wheel
    assert not any(name.startswith(("backend/", "ui/", "examples/")) for name in in_wheel)  # nothing top-level
    entry_points = next(name for name in in_wheel if name.endswith("entry_points.txt"))
    assert "segb = segb_server.backend.cli:main" in zipfile.ZipFile(wheel).read(entry_points).decode()
