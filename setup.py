"""Packaging: the repository's top-level folders are installed under one distribution-specific name.

`backend/`, `ui/`, `examples/`, `sparql/` and `rules/` stay at the top of the repository; the wheel installs them
as `segb_server.backend`, `segb_server.ui`, `segb_server.examples`, `segb_server.sparql` and `segb_server.rules`
(the `.rq` and `.ttl` files as package data), so no top-level `backend` or `ui` package clashes with another
distribution's. `segb_server` itself is a namespace package. Everything else is declared in pyproject.toml.
"""

from setuptools import find_packages, setup

CODE_FOLDERS = ("backend", "ui", "examples")
NAMESPACE = "segb_server"

setup(
    packages=[f"{NAMESPACE}.{name}" for name in find_packages(include=[f"{folder}*" for folder in CODE_FOLDERS])]
    + [f"{NAMESPACE}.sparql", f"{NAMESPACE}.rules"],
    package_dir={f"{NAMESPACE}.{folder}": folder for folder in (*CODE_FOLDERS, "sparql", "rules")},
)
