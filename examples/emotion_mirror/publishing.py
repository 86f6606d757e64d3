"""Publishing only what is new: the robot's graph diffed against what it last published, with the client as it is.

`logger.publish(publisher)` serialises and sends the robot's whole graph every time. That is what the tutorial
does and what the server expects, and re-sent parts cost the server little, but the robot still serialises
everything it ever logged inside its own callback: seconds a publish after a long day. `NewOnly` sends the
triples added since its last publish instead, as a Turtle document of their own, through the same
`SEGBPublisher`. The server stores the same triples either way.

Blank nodes are named by the server from everything a post says about them, so a triple added to a blank node
sent before would name it anew: when the new triples touch a blank node, the whole graph is published (the
tutorial's graph has none). Triples the robot removes are not unsent: the server's log only grows.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rdflib import BNode, Graph
from rdflib.term import Node
from semantic_log_generator import SEGBPublisher, SemanticSEGBLogger


class NewOnly:
    """Publishes a logger's graph one difference at a time (the first publish is the whole graph)."""

    def __init__(self, publisher: SEGBPublisher) -> None:
        self.publisher = publisher
        self._sent: set[Any] = set()

    def publish(self, logger: SemanticSEGBLogger) -> dict[str, Any]:
        document = self.document(logger.graph)
        if document is None:
            return self.publisher.publish_turtle(logger.serialize())
        if not document:  # nothing new: nothing to send
            return {"message": "Nothing new.", "triples_received": 0, "triples_new": 0}
        return self.publisher.publish_turtle(document)

    def document(self, graph: Graph) -> str | None:
        """The triples added since the last call as Turtle (then taken as sent; "" when there are none), or None
        when they touch a blank node (the whole graph is to be published; all of it taken as sent)."""
        new = [triple for triple in graph if triple not in self._sent]
        if not new:
            return ""
        self._sent.update(new)
        if any(isinstance(term, BNode) for triple in new for term in triple):
            return None
        return turtle_of(new, graph)


def turtle_of(triples: Iterable[tuple[Node, Node, Node]], like: Graph) -> str:
    """`triples` as Turtle, with the prefixes of `like` (the robot's own graph)."""
    delta = Graph()
    for prefix, namespace in like.namespaces():
        delta.bind(prefix, namespace, override=True)
    for triple in triples:
        delta.add(triple)
    return delta.serialize(format="turtle")
