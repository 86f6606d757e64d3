"""The import direction the layout promises: API routes → services → store adapters, the UI a client of the
API over HTTP, and shared modules (vocabulary, auth, config, the pages' rule for direction controls) depending
on nothing above them."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "segb_server"


def imports_of(folder: str) -> dict[str, set[str]]:
    """Module file → every module it imports (absolute names)."""
    found: dict[str, set[str]] = {}
    for path in sorted((ROOT / folder).rglob("*.py")):
        names: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                names.add(node.module)
        found[str(path.relative_to(ROOT))] = names
    return found


def offenders(folder: str, forbidden: tuple[str, ...], allowed: tuple[str, ...] = ()) -> list[str]:
    return [
        f"{module} imports {name}"
        for module, names in imports_of(folder).items()
        for name in sorted(names)
        if name.startswith(forbidden) and not name.startswith(allowed)
    ]


@pytest.mark.parametrize(
    ("folder", "forbidden", "allowed"),
    [
        ("backend/services", (f"{PACKAGE}.backend.api", f"{PACKAGE}.ui"), ()),
        ("backend/store", (f"{PACKAGE}.backend.api", f"{PACKAGE}.backend.services", f"{PACKAGE}.ui"), ()),
        (
            "ui",
            (f"{PACKAGE}.backend",),
            (f"{PACKAGE}.backend.config", f"{PACKAGE}.backend.services.direction_controls"),
        ),
    ],
)
def test_layers_import_only_downwards(folder: str, forbidden: tuple[str, ...], allowed: tuple[str, ...]) -> None:
    assert offenders(folder, forbidden, allowed) == []


def test_shared_modules_depend_on_nothing_above_them() -> None:
    project = imports_of("backend")
    assert {name for name in project["backend/vocabulary.py"] if name.startswith(PACKAGE)} == set()
    assert {name for name in project["backend/auth.py"] if name.startswith(PACKAGE)} == {f"{PACKAGE}.backend.config"}
    assert {name for name in project["backend/config.py"] if name.startswith(PACKAGE)} == set()
    shown = project["backend/services/direction_controls.py"]  # the pages' one rule, the UI's as well
    assert {name for name in shown if name.startswith(PACKAGE)} == set()


def test_everything_imports_the_installed_names_never_the_bare_folders() -> None:
    bare = ("backend", "ui", "examples")
    found = [
        f"{module} imports {name}"
        for folder in ("backend", "ui", "examples", "tests", "bench")
        for module, names in imports_of(folder).items()
        for name in names
        if name.split(".")[0] in bare
    ]
    assert found == []


def test_the_api_dependencies_borrow_no_name_of_the_logging_module() -> None:
    """A route reading `principal: Logger` looks like it takes a `logging.Logger`: the role's alias says what the
    caller is instead."""
    import logging

    from segb_server.backend.api import deps

    public = {name for name in vars(deps) if not name.startswith("_")}
    assert public & set(dir(logging)) == set()
    assert deps.Publisher is not None  # the logger role: a robot that publishes its logs


def test_the_bench_uses_the_tests_helpers_and_the_tests_never_use_the_bench() -> None:
    """One direction between the two: the bench starts its real parts and makes its data with the tests' own
    helpers (tests/support: Virtuoso, PostgreSQL, Chromium, the robots' posts), and no test but the bench's own
    (tests/bench) imports the bench: a test helper lives with the tests, a workload with the bench."""
    bench_reaches = offenders("bench", ("tests",), ("tests.support",))
    tests_reach = [line for line in offenders("tests", ("bench",)) if not line.startswith("tests/bench/")]
    assert bench_reaches == [] and tests_reach == []
