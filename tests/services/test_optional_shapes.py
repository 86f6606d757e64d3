"""Every kept view's OPTIONALs are one lookup: one triple pattern or one path, with filters, BINDs and nested
OPTIONALs of their own. The embedded store evaluates such an OPTIONAL for each row with the row's values bound;
an OPTIONAL of two patterns (a join) it evaluates once in full and joins afterwards, so its cost grows with the
log (backend/reading.py, the note on OPTIONALs; docs/reports.md, "Queries both stores plan well")."""

from __future__ import annotations

import pytest
from rdflib.plugins.sparql import prepareQuery
from rdflib.plugins.sparql.parserutils import CompValue

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.reports.folder import FOLDER
from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.sparql.catalog import Catalog, CatalogQuery
from segb_server.backend.services.timeline.kinds import FOLDER as TIMELINE_FOLDER


def _kept() -> list[CatalogQuery]:
    catalog = Catalog(PACKAGE_ROOT / "sparql")
    rules = [rule.query for rule in RuleCatalog(PACKAGE_ROOT / "rules").sparql() if rule.query is not None]
    return [*catalog.under(FOLDER), *catalog.under(TIMELINE_FOLDER), *rules]


def _one_lookup(node: object) -> bool:
    """A pattern the embedded store can evaluate for each row: one triple or path, filtered, extended, or
    extended by OPTIONALs of its own."""
    if not isinstance(node, CompValue):
        return False
    if node.name == "BGP":
        return len(node["triples"]) <= 1
    if node.name in ("Filter", "Extend"):
        return _one_lookup(node["p"])
    if node.name == "LeftJoin":
        return _one_lookup(node["p1"])
    return False


def joined_optionals(text: str) -> list[str]:
    """The OPTIONAL bodies of a query that are more than one lookup, as their triples."""
    found: list[str] = []

    def walk(node: object) -> None:
        if isinstance(node, CompValue):
            if node.name == "LeftJoin" and not _one_lookup(node["p2"]):
                found.append(str(node["p2"].get("triples") or node["p2"].name))
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(prepareQuery(text).algebra)
    return found


@pytest.mark.parametrize("query", _kept(), ids=lambda query: query.name)
def test_each_optional_of_a_kept_view_is_one_lookup(query: CatalogQuery) -> None:
    assert joined_optionals(query.text) == [], query.name


def test_an_optional_of_two_patterns_is_found() -> None:
    text = "SELECT * WHERE { ?m <urn:p> ?x OPTIONAL { ?m <urn:sender> ?h . ?h a <urn:Human> } }"
    assert len(joined_optionals(text)) == 1
    path = "SELECT * WHERE { ?m <urn:p> ?x OPTIONAL { ?m <urn:from>/<urn:sender> ?h FILTER EXISTS { ?h a ?c } } }"
    assert joined_optionals(path) == []


def test_the_shipped_views_are_all_checked() -> None:
    names = {query.name for query in _kept()}
    assert {"reports/conversations", "timeline/message"} <= names, sorted(names)
    rules = {name.removeprefix("rules/") for name in names if name.startswith("rules/")}
    assert rules == {path.stem for path in (PACKAGE_ROOT / "rules").glob("*.rq")}
