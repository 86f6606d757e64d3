"""What one batch of applied journal steps added, indexed once for every view that matches patterns against it.

Each kept query asks "which of the new triples have this predicate (and this object)?" for each of its
patterns: the triples are grouped by predicate once per batch, and the first ask for a predicate makes its
facts (the terms' N-Triples texts) and groups them by object, instead of every view scanning every triple for
every pattern.

`fresh` holds the batch's terms the store held no triple about before the batch (`views/seen_terms.py`): every
triple the store holds about such a term (of this batch or earlier) is among the new triples, so a view may
follow a join from it here (`kept_queries/delta_joins.py`) instead of asking the store.

The views of one batch also ask the store many of the same questions (the report and the timeline's kinds
share their robot and human filters, so the same pairs are looked up for each): `Delta.answer` keeps a
batch's answers by query text, for the batch only. An answer asked after the batch's triples were applied
holds them, and what later steps add reaches the views through the later batches' own questions.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import NamedTuple, TypeVar

from pyoxigraph import Literal, Quad

from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text

Answer = TypeVar("Answer")


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
    def __init__(self, quads: Sequence[Quad], fresh: frozenset[str] = frozenset()) -> None:
        self.quads = quads
        self.fresh = fresh  # N-Triples texts of the terms no triple of the store held before this batch
        self._quads_by_predicate: dict[str, list[Quad]] = {}
        for quad in quads:
            self._quads_by_predicate.setdefault(quad.predicate.value, []).append(quad)
        self._by_predicate: dict[str, list[Fact]] = {}  # made on the first ask for a predicate
        self._by_object: dict[str, dict[str, list[Fact]]] = {}  # predicate → object text → facts
        self._by_subject: dict[str, dict[str, list[Fact]]] = {}  # predicate → subject text → facts
        self.joins: dict[tuple[int, tuple[str, ...]], object] = {}  # a join's number and start → its answer
        self._all_fresh: dict[tuple[tuple[str, ...], bool], bool] = {}
        self._ends: dict[tuple[tuple[str, ...], bool, str | None], frozenset[str]] = {}
        self._answers: dict[str, object] = {}  # query text → the store's answer, for this batch
        self._shared: dict[object, object] = {}  # what views with the same question worked out, for this batch
        self._answers_lock = threading.Lock()  # views of a remote store ask side by side

    @classmethod
    def of(cls, quads: Sequence[Quad], fresh: frozenset[str] = frozenset()) -> Delta:
        return cls(quads, fresh)

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
            by_object = self._by_object[predicate] = _grouped(facts, lambda fact: fact.object_text)
        return by_object.get(object_text, [])

    def about(self, predicate: str, subject_text: str) -> list[Fact]:
        """The new triples with `predicate` whose subject's N-Triples text is `subject_text`."""
        by_subject = self._by_subject.get(predicate)
        if by_subject is None:
            facts = self.with_predicate(predicate)
            by_subject = self._by_subject[predicate] = _grouped(facts, lambda fact: fact.subject_text)
        return by_subject.get(subject_text, [])

    def all_fresh(self, predicates: Sequence[str], *, subject: bool) -> bool:
        """Whether every new triple with one of `predicates` has a fresh term as its subject (or object)."""
        key = (tuple(predicates), subject)
        known = self._all_fresh.get(key)
        if known is None:
            facts = (fact for predicate in predicates for fact in self.with_predicate(predicate))
            known = self._all_fresh[key] = all(
                (fact.subject_text if subject else fact.object_text) in self.fresh for fact in facts
            )
        return known

    def ends(self, predicates: Sequence[str], *, subject: bool, other: str | None = None) -> frozenset[str]:
        """The subjects (or objects) of the new triples with one of `predicates` (and `other` at their other end)."""
        key = (tuple(predicates), subject, other)
        known = self._ends.get(key)
        if known is None:
            facts = [fact for predicate in predicates for fact in self.with_predicate(predicate)]
            known = self._ends[key] = frozenset(
                (fact.subject_text if subject else fact.object_text)
                for fact in facts
                if other is None or (fact.object_text if subject else fact.subject_text) == other
            )
        return known

    def shared(self, key: object, work: Callable[[], Answer]) -> Answer:
        """`work()`'s answer, worked out once per batch for every view with the same `key` (views asking side by
        side may both work it out: the same answer)."""
        with self._answers_lock:
            if key in self._shared:
                return self._shared[key]  # type: ignore[return-value]
        found = work()
        with self._answers_lock:
            return self._shared.setdefault(key, found)  # type: ignore[return-value]

    def answer(self, query: str, ask: Callable[[str], Answer]) -> Answer:
        """The store's answer to `query`, asked once per batch whichever view asks first (`ask(query)`)."""
        with self._answers_lock:
            if query in self._answers:
                return self._answers[query]  # type: ignore[return-value]
        found = ask(query)  # outside the lock: another view's different question need not wait for this one
        with self._answers_lock:
            return self._answers.setdefault(query, found)  # type: ignore[return-value]


def _grouped(facts: list[Fact], key: Callable[[Fact], str]) -> dict[str, list[Fact]]:
    """The facts grouped by `key`, made whole before a view sees it: views of one batch ask side by side, and
    one must never read a grouping another is still filling."""
    grouped: dict[str, list[Fact]] = {}
    for fact in facts:
        grouped.setdefault(key(fact), []).append(fact)
    return grouped
