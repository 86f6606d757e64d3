"""Binding values into a query: into its own top-level WHERE group (at its end), never a subquery's or a
template."""

from __future__ import annotations

import pytest
from pyoxigraph import Literal, NamedNode, Quad, Store

from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import bind_rows, bind_values

EX = "http://example.org/"


@pytest.fixture
def store() -> Store:
    opened = Store()
    opened.extend([Quad(NamedNode(EX + s), NamedNode(EX + "p"), Literal(v)) for s, v in (("a", "1"), ("b", "2"))])
    return opened


def names(store: Store, sparql: str) -> list[str]:
    return sorted(row["s"].value for row in store.query(sparql))  # type: ignore[union-attr]


def test_values_open_the_outer_group_when_a_subquery_comes_first_in_the_text(store: Store) -> None:
    # No WHERE keyword on the outer query: the first `WHERE {` in the text is the subquery's.
    query = f"SELECT ?s {{ {{ SELECT ?s WHERE {{ ?s <{EX}p> ?o }} }} FILTER (?s = ?wanted) }}"
    bound = bind_values(query, {"wanted": NamedNode(EX + "a")})
    assert bound.index("VALUES") < bound.index("SELECT ?s WHERE")
    assert names(store, bound) == [EX + "a"]


@pytest.mark.parametrize("wrap", [False, True])  # opening the group (most stores), around it (Virtuoso)
def test_rows_of_values_join_the_whole_group_filters_included(store: Store, wrap: bool) -> None:
    query = f'SELECT ?s WHERE {{ ?s <{EX}p> ?o OPTIONAL {{ ?s <{EX}q> ?q }} FILTER (?o != "2") }}'
    rows: list[list[Term | None]] = [[NamedNode(EX + "a")], [NamedNode(EX + "b")], [NamedNode(EX + "c")]]
    bound = bind_rows(query, ["s"], rows, wrap=wrap)
    assert names(store, bound) == [EX + "a"]  # b is filtered out, c has no triple


def test_a_construct_template_is_skipped_and_text_in_strings_is_ignored(store: Store) -> None:
    query = f'CONSTRUCT {{ ?s <{EX}q> "WHERE {{" }} WHERE {{ ?s <{EX}p> ?o FILTER (?o = ?wanted) }}'
    bound = bind_values(query, {"wanted": Literal("2")})
    triples = list(store.query(bound))  # type: ignore[arg-type]
    assert [triple.subject.value for triple in triples] == [EX + "b"]  # type: ignore[union-attr]


def test_unbound_parameters_switch_filters_off_and_bad_names_are_refused(store: Store) -> None:
    query = f"SELECT ?s WHERE {{ ?s <{EX}p> ?o FILTER (!BOUND(?wanted) || ?s = ?wanted) }}"
    assert names(store, bind_values(query, {"wanted": None})) == [EX + "a", EX + "b"]
    with pytest.raises(ValueError, match="invalid SPARQL variable"):
        bind_values(query, {"bad name": None})
    with pytest.raises(ValueError, match="no WHERE group"):
        bind_values("ASK", {"x": None})
