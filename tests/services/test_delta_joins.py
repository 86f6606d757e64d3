"""A join followed among a batch's triples gives what the store answers, or gives up.

Random small graphs: an older part the store held before the batch, and the batch itself; a term is fresh when
the older part never mentions it. For random joins (triple patterns and aliases chained from a start variable),
whenever `DeltaJoin.run` answers, its solutions are the store's for the same join from the same start.
"""

from __future__ import annotations

import sys
import threading

from hypothesis import given, settings
from hypothesis import strategies as st
from pyoxigraph import Quad, RdfFormat, Store, parse

from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.kept_queries.delta_joins import Alias, DeltaJoin, Step
from segb_server.backend.services.views.kept_queries.plan_parts import Pattern
from segb_server.backend.store.terms import term_text

EX = "https://example.org/"
NODES = [f"<{EX}n{index}>" for index in range(8)]
PREDICATES = [f"{EX}p{index}" for index in range(3)]

triple = st.tuples(st.sampled_from(NODES), st.sampled_from(PREDICATES), st.sampled_from(NODES))


@st.composite
def joins(draw: st.DrawFn) -> tuple[list[Step], dict[str, frozenset[str]]]:
    """A chain from ?v0: each step a pattern between a bound variable and a new one (either direction, one or two
    predicates), an alias, or a pattern from a bound variable to a constant."""
    steps: list[Step] = []
    bound = ["?v0"]
    for index in range(1, draw(st.integers(1, 4)) + 1):
        source = draw(st.sampled_from(bound))
        kind = draw(st.sampled_from(["forward", "backward", "alias", "constant", "closing"]))
        predicates = frozenset(draw(st.lists(st.sampled_from(PREDICATES), min_size=1, max_size=2)))
        new = f"?v{index}"
        if kind == "alias":
            steps.append(Alias(source, new))
        elif kind == "constant":
            steps.append(Pattern(source, predicates, draw(st.sampled_from(NODES)), 0))
            continue
        elif kind == "closing" and len(bound) > 1:  # both ends bound: a check
            other = draw(st.sampled_from([variable for variable in bound if variable != source]))
            steps.append(Pattern(source, predicates, other, 0))
            continue
        elif kind == "backward":
            steps.append(Pattern(new, predicates, source, 0))
        else:
            steps.append(Pattern(source, predicates, new, 0))
        bound.append(new)
    narrowed = draw(
        st.dictionaries(
            st.sampled_from(bound[1:] or ["?v0"]), st.frozensets(st.sampled_from(NODES), min_size=1), max_size=1
        )
    )
    return steps, narrowed


def variables(step: Step) -> set[str]:
    return {step.source, step.target} if isinstance(step, Alias) else step.variables()


def as_quads(rows: list[tuple[str, str, str]]) -> list[Quad]:
    text = "\n".join(f"{s} <{p}> {o} ." for s, p, o in rows)
    return list(parse(text.encode(), RdfFormat.N_TRIPLES))


def sparql(steps: list[Step], start: str, narrowed: dict[str, frozenset[str]], out: list[str]) -> str:
    body = []
    for step in steps:
        if isinstance(step, Alias):
            body.append(f"BIND ({step.source} AS {step.target})")
        else:
            body.append(step.sparql())
    values = "".join(f"VALUES {var} {{ {' '.join(sorted(allowed))} }} " for var, allowed in narrowed.items())
    # The narrowing last: a BIND may not set a variable a VALUES before it bound.
    return f"SELECT {' '.join(out)} WHERE {{ VALUES ?v0 {{ {start} }} {' '.join(body)} {values}}}"


def store_and_batch(older: list[tuple[str, str, str]], batch: list[tuple[str, str, str]]) -> tuple[Store, Delta]:
    """A store holding the older triples and the batch's, and the batch as the views are told it: its triples the
    store did not hold, and the terms no older triple mentions (fresh)."""
    new = [row for row in dict.fromkeys(batch) if row not in set(older)]
    store = Store()
    store.extend([Quad(q.subject, q.predicate, q.object) for q in as_quads([*older, *new])])
    mentioned = {term for s, _, o in older for term in (s, o)}
    fresh = frozenset(term for s, _, o in new for term in (s, o) if term not in mentioned)
    return store, Delta(as_quads(new), fresh)


@settings(max_examples=600, deadline=None)
@given(
    older=st.lists(triple, max_size=6),
    batch=st.lists(triple, min_size=1, max_size=14),
    join=joins(),
    data=st.data(),
)
def test_a_join_among_the_batch_is_the_stores(
    older: list[tuple[str, str, str]],
    batch: list[tuple[str, str, str]],
    join: tuple[list[Step], dict[str, frozenset[str]]],
    data: st.DataObject,
) -> None:
    steps, narrowed = join
    start = data.draw(st.sampled_from([term for s, _, o in batch for term in (s, o)]))  # mostly fresh
    store, delta = store_and_batch(older, batch)
    out = sorted(
        {v for step in steps for v in ((step.source, step.target) if isinstance(step, Alias) else step.variables())}
        | {"?v0"}
    )
    found = DeltaJoin(steps, ["?v0"], out, narrowed).run(delta, [start])
    if found is None:
        return
    expected = (
        tuple(term_text(solution[name[1:]]) for name in out)
        for solution in store.query(sparql(steps, start, narrowed, out))
    )
    # As sets: what the views make of a join (a row's keys, a filter's pairs) is a set.
    assert set(found) == set(expected)


@settings(max_examples=600, deadline=None)
@given(
    older=st.lists(triple, max_size=6),
    batch=st.lists(triple, min_size=1, max_size=14),
    join=joins(),
    relaxed=st.booleans(),
    data=st.data(),
)
def test_what_a_join_is_told_without_following_it_holds_when_it_is_followed(
    older: list[tuple[str, str, str]],
    batch: list[tuple[str, str, str]],
    join: tuple[list[Step], dict[str, frozenset[str]]],
    relaxed: bool,
    data: st.DataObject,
) -> None:
    """A join said to stay among fresh terms is followed among the batch's triples to the end, and a start value
    `possible` leaves out has no solution in the store (relaxed or not, the join as written has none)."""
    steps, narrowed = join
    start = data.draw(st.sampled_from([term for s, _, o in batch for term in (s, o)] + NODES))
    store, delta = store_and_batch(older, batch)
    out = sorted({v for step in steps for v in variables(step)} | {"?v0"})
    compiled = DeltaJoin(steps, ["?v0"], out, narrowed, relaxed=relaxed)
    if not relaxed and compiled.stays_fresh(delta, [start]):
        assert compiled.run(delta, [start]) is not None
    if start not in compiled.possible(delta, [start]):
        assert list(store.query(sparql(steps, start, narrowed, out))) == []


def test_a_step_from_a_term_the_store_held_before_gives_up() -> None:
    delta = Delta(as_quads([(NODES[0], PREDICATES[0], NODES[1])]), frozenset({NODES[0]}))
    forward = DeltaJoin([Pattern("?a", frozenset({PREDICATES[0]}), "?b", 0)], ["?a"], ["?b"])
    assert forward.run(delta, [NODES[0]]) == [(NODES[1],)]
    assert forward.run(delta, [NODES[1]]) is None  # n1 is not fresh: older triples may start from it
    assert forward.run(Delta(delta.quads), [NODES[0]]) is None  # nothing known fresh: the store answers


def test_a_literal_constant_is_left_to_the_store() -> None:
    delta = Delta(as_quads([(NODES[0], PREDICATES[0], NODES[1])]), frozenset({NODES[0]}))
    join = DeltaJoin(
        [Pattern("?a", frozenset({PREDICATES[0]}), '"1"^^<http://www.w3.org/2001/XMLSchema#integer>', 0)],
        ["?a"],
        ["?a"],
    )
    assert join.run(delta, [NODES[0]]) is None


def test_views_reading_a_batch_side_by_side_see_whole_groupings() -> None:
    # Views ask the same batch for the triples of a predicate by object and by subject at once: none may read a
    # grouping another is still filling.
    rows = [(f"<{EX}s{index}>", PREDICATES[0], NODES[index % 3]) for index in range(20_000)]
    quads = as_quads(rows)
    expected = (sum(1 for _, _, o in rows if o == NODES[2]), 1)
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # threads switch as often as they can
    try:
        for _ in range(20):
            assert asked_side_by_side(Delta(quads)) == [expected] * 4
    finally:
        sys.setswitchinterval(interval)


def asked_side_by_side(delta: Delta) -> list[tuple[int, int]]:
    counts: list[tuple[int, int]] = []
    together = threading.Barrier(4)

    def ask() -> None:
        together.wait()
        by_object = delta.with_predicate(PREDICATES[0], NODES[2])
        counts.append((len(by_object), len(delta.about(PREDICATES[0], f"<{EX}s7>"))))

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return counts


def test_views_following_the_same_join_in_one_batch_share_its_answer(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # The reports and the timeline's kinds follow many of the same chains: a batch works each out once.
    runs: list[tuple[str, ...]] = []
    original = DeltaJoin._run

    def counted(self: DeltaJoin, delta: Delta, values: list[str]) -> object:
        runs.append(tuple(values))
        return original(self, delta, values)

    monkeypatch.setattr(DeltaJoin, "_run", counted)
    step = [Pattern("?a", frozenset({PREDICATES[0]}), "?b", 0)]
    report, timeline = DeltaJoin(step, ["?a"], ["?b"]), DeltaJoin(list(step), ["?a"], ["?b"])
    other = DeltaJoin([Pattern("?a", frozenset({PREDICATES[1]}), "?b", 0)], ["?a"], ["?b"])
    quads = as_quads([(NODES[0], PREDICATES[0], NODES[1]), (NODES[0], PREDICATES[1], NODES[2])])
    delta = Delta(quads, frozenset({NODES[0]}))
    assert report.shape == timeline.shape != other.shape
    assert report.run(delta, [NODES[0]]) == timeline.run(delta, [NODES[0]]) == [(NODES[1],)]
    assert other.run(delta, [NODES[0]]) == [(NODES[2],)]  # another join: its own answer
    assert len(runs) == 2
    assert timeline.run(Delta(quads, frozenset({NODES[0]})), [NODES[0]]) == [(NODES[1],)]  # the next batch asks again
    assert len(runs) == 3


def test_joins_compiled_side_by_side_never_draw_the_same_number() -> None:
    # Views are planned in several threads at once: two distinct joins sharing a number would share answers.
    numbers: dict[int, list[int]] = {}
    together = threading.Barrier(8)
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)

    def compile_joins(thread: int) -> None:
        together.wait()
        numbers[thread] = [
            DeltaJoin([Pattern("?a", frozenset({f"{EX}race{thread}-{index}"}), "?b", 0)], ["?a"], ["?b"]).shape
            for index in range(200)
        ]

    try:
        threads = [threading.Thread(target=compile_joins, args=(thread,)) for thread in range(8)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    finally:
        sys.setswitchinterval(interval)
    drawn = [number for listed in numbers.values() for number in listed]
    assert len(drawn) == 1600 and len(set(drawn)) == 1600
