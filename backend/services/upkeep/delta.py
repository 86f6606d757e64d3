"""What one batch of applied journal steps added, indexed once for every view that matches patterns against it.

Each kept query asks "which of the new triples have this predicate (and this object)?" for each of its
patterns: the triples are grouped by predicate once per batch, and the first ask for a predicate makes its
facts (the terms' N-Triples texts) and groups them by object, instead of every view scanning every triple for
every pattern.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

from pyoxigraph import Literal, Quad

from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text


class Fact(NamedTuple):
    """One new triple: its subject and object, as terms and as N-Triples texts (its predicate is its group's)."""

    subject: Term
    object: Term
    subject_text: str
    object_text: str

    @property
    def literal_object(self) -> bool:
        return isinstance(self.object, Literal)


class Delta:
    def __init__(self, quads: Sequence[Quad]) -> None:
        self.quads = quads
        self._quads_by_predicate: dict[str, list[Quad]] = {}
        for quad in quads:
            self._quads_by_predicate.setdefault(quad.predicate.value, []).append(quad)
        self._by_predicate: dict[str, list[Fact]] = {}  # made on the first ask for a predicate
        self._by_object: dict[str, dict[str, list[Fact]]] = {}  # predicate → object text → facts

    @classmethod
    def of(cls, quads: Sequence[Quad]) -> Delta:
        return cls(quads)

    def __bool__(self) -> bool:
        return bool(self.quads)

    def predicates(self) -> set[str]:
        return set(self._quads_by_predicate)

    def with_predicate(self, predicate: str, object_text: str | None = None) -> list[Fact]:
        """The new triples with `predicate` (and, when given, the object whose N-Triples text is `object_text`)."""
        facts = self._by_predicate.get(predicate)
        if facts is None:
            facts = self._by_predicate[predicate] = [
                Fact(quad.subject, quad.object, term_text(quad.subject), term_text(quad.object))  # type: ignore[arg-type]
                for quad in self._quads_by_predicate.get(predicate, ())
            ]
        if object_text is None or not facts:
            return facts
        by_object = self._by_object.get(predicate)
        if by_object is None:  # `rdf:type` has most triples and most patterns
            by_object = self._by_object[predicate] = {}
            for fact in facts:
                by_object.setdefault(fact.object_text, []).append(fact)
        return by_object.get(object_text, [])
