"""The rules run on one log by itself, with no server: an in-memory store holding just that log.

What `segb check LOG.ttl` prints and `POST /ttl/validate` answers. A robot's client publishes its whole
accumulated graph every time, so one of its posts is its whole log, and the rules see what they would see of
that robot on a server (findings that depend on other robots' logs, such as a shared event another robot named,
cannot show here). Each finding gets the line where the file first names its focus node, when it does.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from pyoxigraph import Quad

from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.rules.evaluation import check_store
from segb_server.backend.services.rules.findings import Finding
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.store.oxigraph import OxigraphStore

GRAPH = "urn:segb:check"
_PREFIX = re.compile(r"^\s*(?:@prefix|PREFIX)\s+([A-Za-z][\w.-]*)?:\s*<([^>]*)>", re.IGNORECASE | re.MULTILINE)


@dataclass(frozen=True)
class CheckReport:
    findings: list[Finding]  # each with `line` (1-based) where the document names its focus, else None

    @property
    def violations(self) -> int:
        return sum(1 for found in self.findings if found["severity"] == "violation")


def check_quads(
    catalog: RuleCatalog, quads: Sequence[Quad], text: str | None = None, shapes: dict[str, ShapeRule] | None = None
) -> CheckReport:
    """Every rule on just `quads`; with the document's `text`, each finding's line."""
    store = OxigraphStore(GRAPH)
    try:
        store.apply([Quad(quad.subject, quad.predicate, quad.object) for quad in quads], 1)
        findings = check_store(catalog, store, shapes)
    finally:
        store.close()
    lines = LineFinder(text) if text is not None else None
    return CheckReport([{**found, "line": lines.line_of(str(found["focus"])) if lines else None} for found in findings])


class LineFinder:
    """The first line of a Turtle or N-Triples document that names an IRI, written in full or with a prefix."""

    def __init__(self, text: str) -> None:
        self.lines = text.splitlines()
        self.prefixes = [(name or "", namespace) for name, namespace in _PREFIX.findall(text)]

    def line_of(self, iri: str) -> int | None:
        spellings = [f"<{iri}>"]
        for name, namespace in self.prefixes:
            if namespace and iri.startswith(namespace) and len(iri) > len(namespace):
                spellings.append(f"{name}:{iri[len(namespace) :]}")
        patterns = [re.compile(re.escape(spelling) + r"(?![\w.:%-]*[\w:%-])") for spelling in spellings]
        for number, line in enumerate(self.lines, start=1):
            if line.lstrip().startswith(("@prefix", "PREFIX", "prefix", "#")):
                continue
            if any(pattern.search(line) for pattern in patterns):
                return number
        return None
