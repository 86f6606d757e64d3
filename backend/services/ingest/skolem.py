"""Deterministic skolemisation: blank nodes become IRIs derived from what surrounds them, never merged.

A blank node's IRI is `<skolem base><32 hex>`, a SHA-256 over its place in its *component* (the blank nodes
connected to it through blank-to-blank triples), where each node is first described by its triples with IRIs
and literals. Consequences:

* the same description re-published (with any labels, in any order, with other triples around it) gets the
  same IRIs, so cumulative re-publishing never duplicates blank nodes;
* two blank nodes are never merged: nodes whose surroundings are identical (a list of repeated values, two
  `[ ex:p "x" ]` on one subject) are told apart by their position in the payload. Swapping two such nodes
  gives the very same triples, so re-publishing still adds nothing;
* adding a triple to a component later gives its nodes new IRIs; the old ones stay.

How a component is placed: a tree (what Turtle's `[ ]` and `( )` always produce) is canonised exactly, in
O(n log n), from its centre (AHU tree hashing), so a 50,000-deep nesting costs well under a second. A component
with cycles (only `_:label` references make them) is coloured by refinement to a fixed point (1-dimensional
Weisfeiler-Leman), individualising the earliest node of any class still holding several, until every class
is a single node; each name carries the component's whole colouring, so different components never share one.
Cyclic components above MAX_CYCLIC_NODES are named by position alone: still never merged, but only a re-post
of the same text is guaranteed to reuse their IRIs.
"""

from __future__ import annotations

from collections import defaultdict, deque
from collections.abc import Sequence
from hashlib import sha256
from typing import Any

from pyoxigraph import BlankNode, NamedNode, Quad

MAX_CYCLIC_NODES = 500
EdgeLabel = tuple[tuple[str, str], ...]  # every (direction, predicate) between two blank nodes, sorted


def might_contain_blank_nodes(data: bytes) -> bool:
    """False when the text cannot contain a blank node in Turtle or N-Triples: a cheap skip of the scan."""
    return b"_:" in data or b"[" in data or b"(" in data


def skolemize(quads: Sequence[Quad], base: str) -> list[Quad]:
    """Return the quads with every blank node replaced by its skolem IRI (unchanged if there are none)."""
    graph = _BlankGraph(quads)
    if not graph.nodes:
        return list(quads)
    names = graph.names()
    iris = {label: NamedNode(base + digest[:32]) for label, digest in names.items()}

    def rename(term: Any) -> Any:  # a quad's subject or object, whatever kind of term
        return iris[term.value] if isinstance(term, BlankNode) else term

    return [Quad(rename(q.subject), q.predicate, rename(q.object), q.graph_name) for q in quads]


def _digest(*parts: object) -> str:
    text = "\x1f".join(str(part) for part in parts)
    return sha256(text.encode("utf-8")).hexdigest()


class _BlankGraph:
    """The blank nodes of a payload: their local descriptions, blank-to-blank edges and first positions."""

    def __init__(self, quads: Sequence[Quad]) -> None:
        self.position: dict[str, int] = {}
        local: dict[str, list[str]] = defaultdict(list)
        pairs: dict[tuple[str, str], list[tuple[str, str]]] = defaultdict(list)
        for index, quad in enumerate(quads):
            subject = quad.subject.value if isinstance(quad.subject, BlankNode) else None
            obj = quad.object.value if isinstance(quad.object, BlankNode) else None
            if subject is None and obj is None:
                continue
            predicate = quad.predicate.value
            for label in (subject, obj):
                if label is not None:
                    self.position.setdefault(label, index)
            if subject is not None and obj is not None:
                if subject == obj:
                    local[subject].append(f"self {predicate}")
                else:
                    pairs[(subject, obj)].append(("out", predicate))
            elif subject is not None:
                local[subject].append(f"out {predicate} {quad.object}")
            elif obj is not None:
                local[obj].append(f"in {predicate} {quad.subject}")
        self.nodes = sorted(self.position, key=self.position.__getitem__)
        self.local = {node: _digest("local", *sorted(local[node])) for node in self.nodes}
        # One undirected edge per pair of nodes, labelled from each side with every triple between them.
        labels: dict[tuple[str, str], list[tuple[str, str]]] = defaultdict(list)
        for (source, target), kinds in pairs.items():
            for _, predicate in kinds:
                labels[(source, target)].append(("out", predicate))
                labels[(target, source)].append(("in", predicate))
        self.neighbours: dict[str, dict[str, EdgeLabel]] = defaultdict(dict)
        for (one, other), kinds in labels.items():
            self.neighbours[one][other] = tuple(sorted(kinds))

    def names(self) -> dict[str, str]:
        """A distinct digest per blank node."""
        placed: dict[str, str] = {}
        seen_components: dict[str, int] = defaultdict(int)
        for component in self._components():
            names = self._place(component)
            # Identical components (automorphic copies) are numbered in payload order.
            signature = _digest("component", *sorted(names.values()))
            copy = seen_components[signature]
            seen_components[signature] += 1
            placed.update({node: _digest(name, copy) if copy else name for node, name in names.items()})
        return placed

    def _components(self) -> list[list[str]]:
        seen: set[str] = set()
        components = []
        for start in self.nodes:
            if start in seen:
                continue
            seen.add(start)
            component, frontier = [start], [start]
            while frontier:
                for other in self.neighbours[frontier.pop()]:
                    if other not in seen:
                        seen.add(other)
                        component.append(other)
                        frontier.append(other)
            components.append(sorted(component, key=self.position.__getitem__))
        return components

    def _place(self, component: list[str]) -> dict[str, str]:
        edges = sum(len(self.neighbours[node]) for node in component) // 2
        if edges == len(component) - 1:
            return _TreeNames(self, component).names()
        if len(component) > MAX_CYCLIC_NODES:
            shape = _digest("large", *sorted(self.local[node] for node in component))
            return {node: _digest(shape, index) for index, node in enumerate(component)}
        return _refined_names(self, component)


class _TreeNames:
    """Canonical names in a tree of blank nodes: subtree hashes bottom-up from the centre, then each node's
    name top-down as its parent's name, the edge and its own subtree, numbered among identical siblings."""

    def __init__(self, graph: _BlankGraph, nodes: list[str]) -> None:
        self.graph = graph
        self.nodes = nodes

    def names(self) -> dict[str, str]:
        centres = self._centres()
        rooted = [(self._subtree_hashes(centre), centre) for centre in centres]
        # Two centres: root at the one whose whole tree hashes lower (equal only when swapping them is an
        # automorphism, where either choice gives the same triples).
        hashes, root = min(rooted, key=lambda pair: (pair[0][pair[1]], self.graph.position[pair[1]]))
        return self._top_down(root, hashes)

    def _centres(self) -> list[str]:
        if len(self.nodes) <= 2:
            return list(self.nodes)
        degree = {node: len(self.graph.neighbours[node]) for node in self.nodes}
        leaves = [node for node in self.nodes if degree[node] <= 1]
        remaining = len(self.nodes)
        while remaining > 2:
            remaining -= len(leaves)
            next_leaves = []
            for leaf in leaves:
                for other in self.graph.neighbours[leaf]:
                    degree[other] -= 1
                    if degree[other] == 1:
                        next_leaves.append(other)
                degree[leaf] = 0
            leaves = next_leaves
        return sorted(leaves, key=self.graph.position.__getitem__)

    def _order_from(self, root: str) -> tuple[list[str], dict[str, str | None]]:
        parent: dict[str, str | None] = {root: None}
        order = [root]
        queue = deque([root])
        while queue:
            node = queue.popleft()
            for other in self.graph.neighbours[node]:
                if other not in parent:
                    parent[other] = node
                    order.append(other)
                    queue.append(other)
        return order, parent

    def _subtree_hashes(self, root: str) -> dict[str, str]:
        order, parent = self._order_from(root)
        hashes: dict[str, str] = {}
        for node in reversed(order):
            children = sorted(
                f"{self.graph.neighbours[node][child]}:{hashes[child]}"
                for child in self.graph.neighbours[node]
                if child != parent[node]
            )
            hashes[node] = _digest("tree", self.graph.local[node], *children)
        return hashes

    def _top_down(self, root: str, hashes: dict[str, str]) -> dict[str, str]:
        order, parent = self._order_from(root)
        names = {root: _digest("root", hashes[root])}
        for node in order:
            siblings: dict[tuple[EdgeLabel, str], int] = defaultdict(int)
            children = [child for child in self.graph.neighbours[node] if child != parent[node]]
            for child in sorted(children, key=self.graph.position.__getitem__):
                label = self.graph.neighbours[node][child]
                rank = siblings[(label, hashes[child])]
                siblings[(label, hashes[child])] += 1
                names[child] = _digest(names[node], label, hashes[child], rank)
        return names


def _refined_names(graph: _BlankGraph, component: list[str]) -> dict[str, str]:
    """Colour refinement to a fixed point, individualising the earliest node of the lowest tied class until
    every node has a colour of its own."""
    colours = {node: graph.local[node] for node in component}
    while True:
        colours = _refine(graph, component, colours)
        classes: dict[str, list[str]] = defaultdict(list)
        for node in component:  # component is in payload order
            classes[colours[node]].append(node)
        tied = [members for members in classes.values() if len(members) > 1]
        if not tied:
            # A colour is a node's place only after as many rounds as its own component needed: two different
            # components can settle with a node alike. The component's whole colouring tells them apart.
            structure = _digest("cyclic", *sorted(colours.values()))
            return {node: _digest(structure, colour) for node, colour in colours.items()}
        chosen = min(tied, key=lambda members: colours[members[0]])[0]
        colours[chosen] = _digest("individual", colours[chosen])


def _refine(graph: _BlankGraph, component: list[str], colours: dict[str, str]) -> dict[str, str]:
    classes = len(set(colours.values()))
    while True:
        refined = {
            node: _digest(
                colours[node],
                *sorted(f"{label}:{colours[other]}" for other, label in graph.neighbours[node].items()),
            )
            for node in component
        }
        count = len(set(refined.values()))
        if count == classes:  # the partition is stable: refining again splits nothing
            return colours
        colours, classes = refined, count
