"""A view of the graph drawn from the index's rows: the nodes a request allows in drawing order, cut at its limit,
the links between them, how many nodes it allows and which of them its search matches."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Collection
from functools import lru_cache

from segb_server.backend.services.graph.candidates import NODE_COLUMNS, NODE_FROM, CandidateQuery, GraphRequest
from segb_server.backend.services.graph.facts import PROV, TERMS, local_name, node_time
from segb_server.backend.services.views import terms
from segb_server.backend.vocabulary import KINDS, compact


def draw(connection: sqlite3.Connection, request: GraphRequest) -> dict[str, object]:
    """The nodes and edges a request draws, most relevant first, cut at `request.limit`; how many nodes it
    allows, and the drawn nodes its search matches."""
    ids = terms.lookup(connection, TERMS, request.iris())
    if request.focus and (request.focus not in ids or not _is_node(connection, ids[request.focus])):
        return {"nodes": [], "edges": [], "truncated": False, "total_nodes": 0, "matches": []}
    query = CandidateQuery(request, ids)
    found = connection.execute(*query.ordered(request.limit + 1)).fetchall()
    truncated = len(found) > request.limit
    kept = found[: request.limit]
    nodes = [_node(row[0], row[1], *row[4:]) for row in kept]
    total = len(kept) if not truncated else _total(connection, query)
    needle = request.q.casefold() if request.q else None
    return {
        "nodes": nodes,
        "edges": _edges(connection, {row[3]: row[4] for row in kept}),
        "truncated": truncated,
        "total_nodes": total,
        "matches": [str(node["id"]) for node in nodes if needle and _matches(node, needle)],
    }


def nodes_of(connection: sqlite3.Connection, iris: Collection[str]) -> dict[str, dict[str, object]]:
    """The nodes of these IRIs as a view draws them, by IRI (an IRI the index holds no node of is left out)."""
    ids = terms.lookup(connection, TERMS, iris)
    found = connection.execute(
        f"SELECT {NODE_COLUMNS} FROM {NODE_FROM} WHERE n.id IN (SELECT value FROM json_each(?))",
        (json.dumps(sorted(ids.values())),),
    )
    return {row[4]: _node(row[0], row[1], *row[4:]) for row in found}


def _is_node(connection: sqlite3.Connection, node: int) -> bool:
    return connection.execute("SELECT 1 FROM graph_nodes WHERE id = ?", (node,)).fetchone() is not None


def _node(rank: int, instant: int, iri: str, kept: str | None, label: str, types: str) -> dict[str, object]:
    node: dict[str, object] = {"id": iri, "label": label, "kind": KINDS[rank], "types": list(_types(types))}
    time = node_time(kept, instant)
    if time:
        node["time"] = time
    return node


@lru_cache(maxsize=4096)
def _types(listed: str) -> tuple[str, ...]:
    """A node's stored type list as drawn (CURIEs), made once: a graph of thousands of nodes has a few dozen
    distinct lists."""
    return tuple(sorted(compact(type_) for type_ in json.loads(listed)))


def _total(connection: sqlite3.Connection, query: CandidateQuery) -> int:
    """How many nodes the request allows: kept as a count for the unfiltered view, counted otherwise."""
    if query.unfiltered:
        return int(connection.execute("SELECT nodes FROM graph_state").fetchone()[0])
    return int(connection.execute(*query.count()).fetchone()[0])


def _edges(connection: sqlite3.Connection, drawn: dict[int, str]) -> list[dict[str, str]]:
    """The links between drawn nodes (id → IRI). The client doubles most links with a PROV copy
    (segb:wasPerformedBy + prov:wasAssociatedWith, schema:sender + prov:wasAttributedTo, ...); drawing both
    only doubles every arrow."""
    listed = json.dumps(list(drawn))
    found = connection.execute(
        "SELECT source, predicate, target FROM graph_links WHERE source IN (SELECT value FROM json_each(?)) "
        "AND target IN (SELECT value FROM json_each(?))",
        (listed, listed),
    ).fetchall()
    predicates = terms.texts_of(connection, TERMS, {predicate for _, predicate, _ in found})
    links = sorted((drawn[s], predicates[p], drawn[o]) for s, p, o in found)
    primary_pairs = {(s, o) for s, p, o in links if not p.startswith(PROV)}
    labels = {p: local_name(p) for p in {p for _, p, _ in links}}  # a few predicates label thousands of links
    return [
        {"id": f"{s} {p} {o}", "source": s, "target": o, "predicate": p, "label": labels[p]}
        for s, p, o in links
        if not (p.startswith(PROV) and (s, o) in primary_pairs)
    ]


def _matches(node: dict[str, object], needle: str) -> bool:
    return needle in str(node["label"]).casefold() or needle in str(node["id"]).casefold()
