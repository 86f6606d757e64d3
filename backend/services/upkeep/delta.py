"""What one batch of applied journal steps added, indexed once for every view that matches patterns against it.

Each kept query asks "which of the new triples have this predicate (and this object)?" for each of its
patterns: the triples are grouped by predicate, and by predicate and object, once per batch, with their terms'
N-Triples texts computed once, instead of every view scanning every triple for every pattern.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from pyoxigraph import Literal, Quad

from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text


@dataclass(frozen=True, slots=True)
class Fact:
    """One new triple: its subject and object, as terms and as N-Triples texts (its predicate is its group's)."""

    subject: Term
    object: Term
    subject_text: str
    object_text: str

    @property
    def literal_object(self) -> bool:
        return isinstance(self.object, Literal)


@dataclass
class Delta:
    quads: Sequence[Quad]
    _by_predicate: dict[str, list[Fact]] = field(default_factory=dict)
    _by_object: dict[str, dict[str, list[Fact]]] = field(default_factory=dict)  # predicate → object text → facts

    @classmethod
    def of(cls, quads: Sequence[Quad]) -> Delta:
        delta = cls(quads)
        by_predicate = delta._by_predicate
        for quad in quads:
            subject, value = quad.subject, quad.object
            fact = Fact(subject, value, term_text(subject), term_text(value))  # type: ignore[arg-type]
            by_predicate.setdefault(quad.predicate.value, []).append(fact)
        return delta

    def __bool__(self) -> bool:
        return bool(self.quads)

    def predicates(self) -> set[str]:
        return set(self._by_predicate)

    def with_predicate(self, predicate: str, object_text: str | None = None) -> list[Fact]:
        """The new triples with `predicate` (and, when given, the object whose N-Triples text is `object_text`)."""
        facts = self._by_predicate.get(predicate, [])
        if object_text is None or not facts:
            return facts
        by_object = self._by_object.get(predicate)
        if by_object is None:  # made on the first ask: `rdf:type` has most triples and most patterns
            by_object = self._by_object[predicate] = {}
            for fact in facts:
                by_object.setdefault(fact.object_text, []).append(fact)
        return by_object.get(object_text, [])
