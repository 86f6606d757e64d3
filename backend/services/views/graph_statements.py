"""What the graph index holds about resources, told as rows of the store's resource queries, so that a resource's
summary can be read from the index rather than the store when it needs only what the index keeps."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Collection, Sequence

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.graph.facts import RDF_TYPE, TERMS, chunks, typed_literal
from segb_server.backend.services.views import terms
from segb_server.backend.store.base import Term


def kept_statements(
    connection: sqlite3.Connection,
    kept_literals: frozenset[str],
    iris: Sequence[str],
    incoming: Collection[str],
    incoming_limit: int,
    pending: Sequence[Quad],
) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
    """What the index holds about `iris`, as rows of the store's resource queries (`resource`, `predicate`,
    `value`): every link and type from each, its kept literals, and up to `incoming_limit` + 1 links with
    the `incoming` predicates pointing at each. `pending`: triples the store has and the index does not
    have yet (applied steps on their way to it), told as if the index held them."""
    wanted = list(dict.fromkeys(iris))
    ids = terms.lookup(connection, TERMS, [*wanted, *incoming])
    nodes = [ids[iri] for iri in wanted if iri in ids]
    outgoing: list[dict[str, Term]] = []
    pointing: list[dict[str, Term]] = []
    type_predicate = NamedNode(RDF_TYPE)
    for chunk in chunks(nodes):
        marks = ", ".join("?" * len(chunk))
        for source, predicate, target in connection.execute(
            f"SELECT s.text, p.text, o.text FROM graph_links l JOIN graph_terms s ON s.id = l.source "
            f"JOIN graph_terms p ON p.id = l.predicate JOIN graph_terms o ON o.id = l.target "
            f"WHERE l.source IN ({marks})",
            chunk,
        ):
            outgoing.append({"resource": NamedNode(source), "predicate": NamedNode(predicate),
                             "value": NamedNode(target)})  # fmt: skip
        for iri, listed in connection.execute(
            f"SELECT t.text, s.types FROM graph_nodes n JOIN graph_terms t ON t.id = n.id "
            f"JOIN graph_typesets s ON s.id = n.typeset WHERE n.id IN ({marks})",
            chunk,
        ):
            outgoing += [{"resource": NamedNode(iri), "predicate": type_predicate, "value": NamedNode(type_)}
                         for type_ in json.loads(listed)]  # fmt: skip
        for iri, predicate, value, datatype, language in connection.execute(
            f"SELECT DISTINCT s.text, p.text, l.value, d.text, l.language FROM graph_literals l "
            f"JOIN graph_terms s ON s.id = l.node JOIN graph_terms p ON p.id = l.predicate "
            f"LEFT JOIN graph_terms d ON d.id = l.datatype WHERE l.node IN ({marks})",
            chunk,
        ):
            outgoing.append({"resource": NamedNode(iri), "predicate": NamedNode(predicate),
                             "value": typed_literal(value, datatype, language)})  # fmt: skip
    predicates = sorted(ids[predicate] for predicate in incoming if predicate in ids)
    marks = ", ".join("?" * len(predicates))
    for iri in wanted:
        if iri not in ids or not predicates:
            continue
        for predicate, source in connection.execute(
            f"SELECT p.text, s.text FROM (SELECT predicate, source FROM graph_links WHERE target = ? "
            f"AND predicate IN ({marks}) LIMIT ?) l JOIN graph_terms p ON p.id = l.predicate "
            f"JOIN graph_terms s ON s.id = l.source",
            [ids[iri], *predicates, incoming_limit + 1],
        ):
            pointing.append({"resource": NamedNode(iri), "predicate": NamedNode(predicate),
                             "value": NamedNode(source)})  # fmt: skip
    if not pending:
        return outgoing, pointing
    more_out, more_in = _pending_statements(pending, set(iris), set(incoming), kept_literals)
    # A pending triple may have reached the index since its rows were read: each statement is told once.
    return _unique(outgoing + more_out), _unique(pointing + more_in)


def _pending_statements(
    quads: Sequence[Quad], iris: set[str], incoming: set[str], kept_literals: frozenset[str]
) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
    """The rows `GraphIndex.statements` would read about `iris` once `quads` are in the index: what the facts
    keep of them (links, types, kept literals, from named subjects only)."""
    outgoing: list[dict[str, Term]] = []
    pointing: list[dict[str, Term]] = []
    for quad in quads:
        subject, predicate, value = quad.subject, quad.predicate, quad.object
        if not isinstance(subject, NamedNode):
            continue
        if isinstance(value, NamedNode):
            if subject.value in iris:
                outgoing.append({"resource": subject, "predicate": predicate, "value": value})
            if value.value in iris and predicate.value in incoming and predicate.value != RDF_TYPE:
                pointing.append({"resource": value, "predicate": predicate, "value": subject})
        elif isinstance(value, Literal) and subject.value in iris and predicate.value in kept_literals:
            outgoing.append({"resource": subject, "predicate": predicate, "value": value})
    return outgoing, pointing


def _unique(rows: list[dict[str, Term]]) -> list[dict[str, Term]]:
    return list({(row["resource"], row["predicate"], row["value"]): row for row in rows}.values())
