"""Deterministic skolemisation: blank nodes become IRIs derived from what surrounds them.

The rule (documented in the README): a blank node's IRI is `<skolem base><32 hex>`, where the hex is a
SHA-256 over the node's incident triples, refined round by round with the digests of neighbouring blank
nodes (colour refinement) until the partition of blank nodes stops changing. Consequences:

* the same description re-published (with any labels, in any order, with other triples around it)
  gets the same IRI, so cumulative re-publishing never duplicates blank nodes;
* two blank nodes with identical surroundings (indistinguishable in the graph) become one node;
* adding a triple to a blank node's description later gives it a new IRI; the old one stays.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from hashlib import sha256

from pyoxigraph import BlankNode, NamedNode, Quad

_MAX_ROUNDS = 16


def might_contain_blank_nodes(data: bytes) -> bool:
    """False when the text cannot contain a blank node in Turtle or N-Triples: a cheap skip of the scan."""
    return b"_:" in data or b"[" in data or b"(" in data


def skolemize(quads: Sequence[Quad], base: str) -> list[Quad]:
    """Return the quads with every blank node replaced by its skolem IRI (unchanged if there are none)."""
    incident: dict[str, list[Quad]] = defaultdict(list)
    for quad in quads:
        if isinstance(quad.subject, BlankNode):
            incident[quad.subject.value].append(quad)
        if isinstance(quad.object, BlankNode) and quad.object != quad.subject:
            incident[quad.object.value].append(quad)
    if not incident:
        return list(quads)

    colours = _refine(incident)
    iris = {label: NamedNode(base + colour[:32]) for label, colour in colours.items()}

    def rename(term):  # type: ignore[no-untyped-def]
        return iris[term.value] if isinstance(term, BlankNode) else term

    return [Quad(rename(q.subject), q.predicate, rename(q.object), q.graph_name) for q in quads]


def _refine(incident: dict[str, list[Quad]]) -> dict[str, str]:
    """Colour each connected group of blank nodes on its own, so unrelated data never changes its IRIs."""
    colours: dict[str, str] = {}
    for component in _components(incident):
        local = {label: "" for label in component}
        classes = 1
        for _ in range(_MAX_ROUNDS):
            local = {label: _signature(label, incident[label], local) for label in component}
            refined = len(set(local.values()))
            if refined == classes:
                break
            classes = refined
        colours.update(local)
    return colours


def _components(incident: dict[str, list[Quad]]) -> list[list[str]]:
    neighbours: dict[str, set[str]] = defaultdict(set)
    for label, edges in incident.items():
        for quad in edges:
            for term in (quad.subject, quad.object):
                if isinstance(term, BlankNode) and term.value != label:
                    neighbours[label].add(term.value)
    seen: set[str] = set()
    components = []
    for start in incident:
        if start in seen:
            continue
        seen.add(start)
        component, frontier = [start], [start]
        while frontier:
            for other in neighbours[frontier.pop()]:
                if other not in seen:
                    seen.add(other)
                    component.append(other)
                    frontier.append(other)
        components.append(component)
    return components


def _signature(label: str, edges: list[Quad], colours: dict[str, str]) -> str:
    def show(term, is_self: bool) -> str:  # type: ignore[no-untyped-def]
        if is_self:
            return "_:self"
        if isinstance(term, BlankNode):
            return "_:" + colours[term.value]
        return str(term)

    lines = []
    for quad in edges:
        subject_is_self = isinstance(quad.subject, BlankNode) and quad.subject.value == label
        object_is_self = isinstance(quad.object, BlankNode) and quad.object.value == label
        lines.append(f"{show(quad.subject, subject_is_self)} {quad.predicate} {show(quad.object, object_is_self)}")
    lines.sort()
    digest = sha256(colours[label].encode())
    for line in lines:
        digest.update(line.encode("utf-8"))
        digest.update(b"\n")
    return digest.hexdigest()
