"""Skolemisation rule: same surroundings, same IRI; unrelated data never changes it."""

from __future__ import annotations

from pyoxigraph import NamedNode, RdfFormat, parse

from segb_server.backend.services.skolem import skolemize

BASE = "http://amor-segb/.well-known/genid/"


def skolem_iris(turtle: str) -> dict[str, str]:
    """subject-or-object IRI minted for each blank node, keyed by the predicate that points to it."""
    quads = skolemize(list(parse(turtle.encode(), RdfFormat.TURTLE)), BASE)
    return {
        q.predicate.value: q.object.value
        for q in quads
        if isinstance(q.object, NamedNode) and q.object.value.startswith(BASE)
    }


PREFIX = "@prefix ex: <https://ex.org/> .\n"


def test_labels_and_order_do_not_matter() -> None:
    one = skolem_iris(PREFIX + "ex:a ex:pose [ ex:x 1 ; ex:y 2 ] .")
    two = skolem_iris(PREFIX + "_:q ex:y 2 .\n_:q ex:x 1 .\nex:a ex:pose _:q .")
    assert one == two
    assert len(one["https://ex.org/pose"]) == len(BASE) + 32


def test_unrelated_blank_nodes_elsewhere_do_not_change_an_iri() -> None:
    alone = skolem_iris(PREFIX + "ex:a ex:pose [ ex:x 1 ] .")
    crowded = skolem_iris(
        PREFIX + "ex:a ex:pose [ ex:x 1 ] .\nex:b ex:chain [ ex:next [ ex:next [ ex:v 3 ] ] ] .\nex:c ex:q [ ex:x 1 ] ."
    )
    assert alone["https://ex.org/pose"] == crowded["https://ex.org/pose"]


def test_different_surroundings_give_different_iris() -> None:
    iris = skolem_iris(PREFIX + "ex:a ex:p [ ex:x 1 ] .\nex:b ex:q [ ex:x 1 ] .")
    assert iris["https://ex.org/p"] != iris["https://ex.org/q"]


def test_nested_blank_nodes_are_told_apart_by_their_neighbours() -> None:
    iris = skolem_iris(PREFIX + "ex:a ex:p [ ex:inner [ ex:v 1 ] ] .\nex:a ex:q [ ex:inner [ ex:v 2 ] ] .")
    assert iris["https://ex.org/p"] != iris["https://ex.org/q"]
    assert len(set(iris.values())) == 3  # p, q and the two inner nodes, keyed by predicate 'inner' once


def test_graphs_without_blank_nodes_are_returned_unchanged() -> None:
    quads = list(parse((PREFIX + "ex:a ex:p ex:b .").encode(), RdfFormat.TURTLE))
    assert skolemize(quads, BASE) == quads
