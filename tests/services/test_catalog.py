"""The query catalog: headers, typed parameters, and every shipped .rq file runs on both kinds of store."""

from __future__ import annotations

from pathlib import Path

import pytest

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.errors import InvalidParameter, NotFound
from segb_server.backend.services.sparql.catalog import Catalog, paged
from segb_server.backend.store.base import select
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.store.query_form import query_form

SHIPPED = Catalog(PACKAGE_ROOT / "sparql")


def write(directory: Path, name: str, text: str) -> None:
    path = directory / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_header_declares_title_description_and_typed_parameters(tmp_path: Path) -> None:
    write(
        tmp_path,
        "reports/demo.rq",
        "# title: Demo\n# description: Things by robot.\n"
        "# param robot: iri — only this robot\n# param threshold: decimal = 0.75 — lowest value\n"
        "SELECT ?s WHERE { ?s ?p ?o }\n",
    )
    query = Catalog(tmp_path).get("reports/demo")
    assert (query.title, query.description) == ("Demo", "Things by robot.")
    assert query.parameters["robot"].type == "iri"
    assert query.parameters["robot"].help == "only this robot"
    assert query.parameters["threshold"].default == "0.75"
    bindings = query.bindings({"robot": "https://ex.org/ari"})
    assert str(bindings["param_robot"]) == "<https://ex.org/ari>"
    assert bindings["param_threshold"].value == "0.75"  # type: ignore[union-attr]


def test_bad_and_unknown_parameters_name_the_parameter(tmp_path: Path) -> None:
    write(tmp_path, "q.rq", "# param since: dateTime\nSELECT * WHERE { ?s ?p ?o }\n")
    query = Catalog(tmp_path).get("q")
    with pytest.raises(InvalidParameter, match="'since'"):
        query.bindings({"since": "yesterday"})
    with pytest.raises(InvalidParameter, match="'robot': not a parameter"):
        query.bindings({"robot": "https://ex.org/ari"})
    with pytest.raises(NotFound):
        Catalog(tmp_path).get("nope")


def test_paging_appends_only_integers() -> None:
    assert paged("SELECT * WHERE {}", 10, 20).endswith("LIMIT 10\nOFFSET 20")
    assert paged("SELECT * WHERE {}", None, None) == "SELECT * WHERE {}"


@pytest.mark.parametrize("query", list(SHIPPED), ids=lambda query: query.name)
def test_every_shipped_query_is_documented_and_runs_unbound(query) -> None:  # type: ignore[no-untyped-def]
    assert query.title != query.name and query.description
    assert "LIMIT" not in query.text.upper().split("WHERE", 1)[-1] or query.name.startswith("examples/")
    store = OxigraphStore("http://amor-segb/events")
    if query_form(query.text) == "select":
        assert select(store, paged(query.text, 10, 0), query.bindings({})).rows == []
    else:
        list(store.query(query.text, query.bindings({})))  # type: ignore[call-overload]
    store.close()
