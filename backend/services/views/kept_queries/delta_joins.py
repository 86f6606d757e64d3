"""Joins followed among a batch's own triples instead of asked of the store, where that gives the same answer.

A view asks the store which of its keys (or facet pairs) a batch's new triples reach: a join from each new
triple through the query's patterns. Most of those joins start from resources the batch itself introduced (a
robot's new activity, the message it produced, the visitor it met): every triple the store holds about such a
`fresh` term is one of the batch's own (`views/seen_terms.py`), so a step from it can be taken among the
batch's triples, with no store lookup. A join is followed here only while every step goes from a fresh term;
the first step from any other term (the robot, a model, a class: a hub with years of history) gives up, and
that join is asked of the store as before. The answers are the store's: the differential tests compare the
views kept this way with full evaluations, on both stores.

A join's order is fixed when the query is planned (`DeltaJoin`): which variables are bound where does not
depend on the values, so a batch only runs the steps.

Views of one batch follow many of the same joins (the reports and the timeline's kinds share their chains from
an activity to its message, from a message to its human; measured on one robot's posts, more than half of a
batch's joins): a compiled join's steps get a number (`_shape_of`, one number per distinct compiled join,
handed out under a lock), and the batch keeps each answer by number and start (`Delta.joins`), for the batch
only. Two joins with the same number run the same steps from the same start: they have the same answer.

A `relaxed` join answers a weaker question, whether a key the batch introduced can have any row at all: the
steps it cannot take among the batch's triples are left out, and fewer patterns only allow more solutions. No
solution then means the query has none for that key, whose evaluation the view skips.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from segb_server.backend.services.views.delta import Delta, Fact
from segb_server.backend.services.views.kept_queries.plan_parts import Pattern


@dataclass(frozen=True)
class Alias:
    """`BIND (?source AS ?target)`."""

    source: str
    target: str


Step = Pattern | Alias

_SHAPES: dict[tuple[object, ...], int] = {}  # a compiled join's steps and ends → its number
_SHAPES_LOCK = threading.Lock()  # views are planned side by side: no two distinct joins may draw one number
_UNKNOWN = object()


def _shape_of(signature: tuple[object, ...]) -> int:
    """The number of the compiled join `signature` describes: the same for equal signatures, distinct otherwise."""
    with _SHAPES_LOCK:
        return _SHAPES.setdefault(signature, len(_SHAPES))


@dataclass(frozen=True)
class _End:
    """One end of a triple pattern in a compiled join: a constant text, a slot bound before the step, or a slot
    the step binds (with the texts it allows, if its group's VALUES narrow it)."""

    constant: str | None = None
    slot: int = -1
    binds: bool = False
    allowed: frozenset[str] | None = None


@dataclass(frozen=True)
class _Hop:
    predicates: tuple[str, ...]
    subject: _End
    object: _End


@dataclass(frozen=True)
class _Found:
    """Where a slot's value comes from: the start's values (`start`, an index), or the subject (or object) of the
    batch's triples with one of `predicates` (the hop that bound it)."""

    start: int = -1
    predicates: tuple[str, ...] = ()
    subject: bool = False


@dataclass(frozen=True)
class _Copy:
    """An alias: `target` takes `source`'s term (or, when already bound, must equal it)."""

    source: int
    target: int
    binds: bool
    allowed: frozenset[str] | None


class DeltaJoin:
    """`steps` (triple patterns and aliases, joined) from the variables `start`, giving the variables `out`."""

    def __init__(
        self,
        steps: Sequence[Step],
        start: Sequence[str],
        out: Sequence[str],
        allowed: Mapping[str, frozenset[str]] | None = None,
        *,
        relaxed: bool = False,
    ) -> None:
        allowed = dict(allowed or {})
        self.relaxed = relaxed
        self._start_allowed = [allowed.get(variable) for variable in start]
        self._ops: list[_Hop | _Copy] = []
        slots = {variable: index for index, variable in enumerate(start)}
        # What `stays_fresh` checks: for each hop, where the values it may step from come from (any one will do).
        found = {index: _Found(start=index) for index in range(len(start))}
        self._guards: list[tuple[_Found, ...]] = []
        self._guarded = True  # false once a hop steps from a constant alone (a class, a hub: never fresh)
        # A literal is written in more than one way: only IRIs are compared as texts here, the rest by the store.
        self.usable = all(text.startswith("<") for values in allowed.values() for text in values)
        remaining = list(steps)
        while remaining and self.usable:
            index = _next_step(remaining, set(slots))
            if index is None:
                self.usable = relaxed  # a step from nothing bound would be a scan: the store's work
                break
            step = remaining.pop(index)
            if isinstance(step, Alias):
                binds = step.target not in slots
                target = slots.setdefault(step.target, len(slots))
                self._ops.append(_Copy(slots[step.source], target, binds, allowed.get(step.target)))
                if binds:
                    found[target] = found[slots[step.source]]
                continue
            literal = not step.object.startswith("?") and not step.object.startswith("<")
            if literal or (step.subject == step.object and step.subject not in slots):  # a literal; `?x p ?x`
                self.usable = relaxed
                continue
            subject = _end(step.subject, slots, allowed)
            object_ = _end(step.object, slots, allowed)
            hop = _Hop(tuple(sorted(step.predicates)), subject, object_)
            self._ops.append(hop)
            guard = tuple(found[end.slot] for end in (subject, object_) if end.constant is None and not end.binds)
            self._guards.append(guard)
            self._guarded = self._guarded and bool(guard)
            for end, is_subject in ((subject, True), (object_, False)):
                if end.binds:
                    found[end.slot] = _Found(predicates=hop.predicates, subject=is_subject)
        self._width = len(slots)
        self._out = [slots.get(variable, -1) for variable in out]
        if -1 in self._out:
            self.usable = False
        # The hops with the first start variable at one end, and what is at the other when it is a constant: a
        # fresh start value that no new triple has there can have no solution (`possible`)
        self._from_start = [
            (hop.predicates, end is hop.subject, other.constant)
            for hop in self._ops
            if isinstance(hop, _Hop)
            for end, other in ((hop.subject, hop.object), (hop.object, hop.subject))
            if start and end.slot == 0 and not end.binds and end.constant is None
        ]
        # Whether every `out` value is the subject or object of a triple a hop matched (not one an alias copied)
        self.hop_binds_out = self.usable and all(found[slot].start < 0 and found[slot].predicates for slot in self._out)
        signature = (tuple(self._ops), tuple(self._out), tuple(self._start_allowed), self._width, relaxed, self.usable)
        self.shape = _shape_of(signature)

    def run(self, delta: Delta, values: Sequence[str]) -> list[tuple[str, ...]] | None:
        """The `out` terms of each solution extending `values` (the texts of `start`), found among the delta's
        triples; None when a step would start from a term that is not fresh (the store may hold older triples
        about it), or the join cannot be followed here at all."""
        if not self.usable or not delta.fresh:
            return None
        key = (self.shape, tuple(values))
        known = delta.joins.get(key, _UNKNOWN)
        if known is not _UNKNOWN:
            return known  # type: ignore[return-value]
        found = self._run(delta, values)
        delta.joins[key] = found  # views asking side by side may both work it out: the same answer
        return found

    def possible(self, delta: Delta, starts: Iterable[str]) -> list[str]:
        """Of the values of the (first) start variable, those the join may find a solution from: all but the fresh
        ones some hop from the start finds no new triple for (every triple about a fresh term is new). One set
        operation a hop for a whole batch, where `run` would follow the join from each value."""
        fresh = delta.fresh
        possible = list(starts)
        for predicates, subject, other in self._from_start if self.usable and fresh else ():
            there = delta.ends(predicates, subject=subject, other=other)
            possible = [value for value in possible if value in there or value not in fresh]
        return possible

    def stays_fresh(self, delta: Delta, values: Sequence[str]) -> bool:
        """Whether following the join from `values` is sure to step only from fresh terms, told without following
        it: each hop's start is among the start's `values` that are fresh, or is bound by an earlier hop from the
        batch's triples of predicates whose terms there are all fresh. Every triple such a join matches is then
        one of the batch's."""
        if not (self.usable and self._guarded and delta.fresh):
            return False
        for guard in self._guards:
            for source in guard:
                if (
                    values[source.start] in delta.fresh
                    if source.start >= 0
                    else delta.all_fresh(source.predicates, subject=source.subject)
                ):
                    break
            else:
                return False
        return True

    def _run(self, delta: Delta, values: Sequence[str]) -> list[tuple[str, ...]] | None:
        for value, allowed in zip(values, self._start_allowed, strict=True):
            if allowed is not None and value not in allowed:
                return []
        rows: list[list[str | None]] = [[*values, *([None] * (self._width - len(values)))]]
        fresh = delta.fresh
        for op in self._ops:
            if isinstance(op, _Copy):
                rows = _copied(rows, op)
                continue
            extended: list[list[str | None]] = []
            for row in rows:
                subject = op.subject.constant if op.subject.constant is not None else row[op.subject.slot]
                object_ = op.object.constant if op.object.constant is not None else row[op.object.slot]
                if subject is not None and subject in fresh:
                    facts: list[Fact] = [fact for p in op.predicates for fact in delta.about(p, subject)]
                elif object_ is not None and object_ in fresh:
                    facts = [fact for p in op.predicates for fact in delta.with_predicate(p, object_)]
                elif self.relaxed:
                    extended.append(row)  # the step left out for this row (its variable stays unbound)
                    continue
                else:
                    return None  # the store may hold older triples of this step
                for fact in facts:
                    found = _extended(row, op.subject, subject, fact.subject_text)
                    if found is not None:
                        found = _extended(found, op.object, object_, fact.object_text)
                    if found is not None:
                        extended.append(found)
            rows = extended
            if not rows:
                return []
        return [tuple(row[slot] for slot in self._out) for row in rows]  # type: ignore[misc]


def _end(term: str, slots: dict[str, int], allowed: Mapping[str, frozenset[str]]) -> _End:
    if not term.startswith("?"):
        return _End(constant=term)
    if term in slots:
        return _End(slot=slots[term])
    slots[term] = len(slots)
    return _End(slot=slots[term], binds=True, allowed=allowed.get(term))


def _extended(row: list[str | None], end: _End, known: str | None, text: str) -> list[str | None] | None:
    """`row` with `end` taking `text` from a matching triple; None when it cannot."""
    if not end.binds and known is not None:
        return row if known == text else None
    if end.allowed is not None and text not in end.allowed:
        return None
    copy = row.copy()
    copy[end.slot] = text  # (a relaxed join's variable left unbound by a step it left out is bound here)
    return copy


def _copied(rows: list[list[str | None]], op: _Copy) -> list[list[str | None]]:
    kept = []
    for row in rows:
        value = row[op.source]
        if value is None:  # a relaxed join left its source unbound: nothing to compare or copy
            kept.append(row)
            continue
        if not op.binds and row[op.target] is not None:
            if row[op.target] == value:
                kept.append(row)
            continue
        if op.allowed is not None and value not in op.allowed:
            continue
        copy = row.copy()
        copy[op.target] = value
        kept.append(copy)
    return kept


def _next_step(steps: list[Step], bound: set[str]) -> int | None:
    """The next step to take: an alias from a bound variable, else a pattern with a bound variable, else one
    with a constant (a class, often a hub)."""
    for index, step in enumerate(steps):
        if isinstance(step, Alias) and step.source in bound:
            return index
    for index, step in enumerate(steps):
        if isinstance(step, Pattern) and (step.subject in bound or step.object in bound):
            return index
    for index, step in enumerate(steps):
        if isinstance(step, Pattern) and (not step.subject.startswith("?") or not step.object.startswith("?")):
            return index
    return None
