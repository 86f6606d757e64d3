"""No dead code: every top-level function and class of the server, the UI and the example robot is used somewhere
(by the project, its tests or the bench; named in a string, as uvicorn's factory is, or in a template)."""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFINING = ("backend", "ui", "examples")
USING = ("backend", "ui", "examples", "bench", "tests")
FACTORY = re.compile(r"^[\w.]+:(\w+)$")  # "package.module:name", as uvicorn is given an app factory


@cache
def used_names() -> frozenset[str]:
    """Every name the code reads (`name`, `thing.name`, imports), names in `module:name` strings, and every word
    of the UI's templates."""
    names: set[str] = set()
    for folder in USING:
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
                if isinstance(node, ast.Name):
                    names.add(node.id)
                elif isinstance(node, ast.Attribute):
                    names.add(node.attr)
                elif isinstance(node, ast.alias):  # imported under another name
                    names.add(node.name.rpartition(".")[2])
                elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                    names.update(FACTORY.findall(node.value))
    for path in (ROOT / "ui" / "templates").rglob("*.html"):
        names.update(path.read_text(encoding="utf-8").replace("(", " ").replace(".", " ").split())
    return frozenset(names)


@cache
def definitions() -> dict[str, set[str]]:
    """Module file → its top-level functions and classes, but those a decorator registers (routes, validators)."""
    found: dict[str, set[str]] = {}
    for folder in DEFINING:
        for path in sorted((ROOT / folder).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
            found[str(path.relative_to(ROOT))] = {
                node.name
                for node in tree.body
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)
                and not node.decorator_list
                and not node.name.startswith("__")
            }
    return found


def test_every_top_level_function_and_class_is_used() -> None:
    used = used_names()
    unused = {f"{module}: {name}" for module, names in definitions().items() for name in names if name not in used}
    assert sorted(unused) == []
