"""A plain report's filter indexes hold each row's head (layout.py, `head_of`): a page chosen by heads holds the
first rows of the whole order only if heads never sort against their keys."""

from __future__ import annotations

import itertools
import random

from pyoxigraph import BlankNode, Literal, NamedNode

from segb_server.backend.services.views.kept_queries.encoding import DATE_TIME, SEPARATOR, sort_key
from segb_server.backend.services.views.kept_queries.layout import head_of
from segb_server.backend.store.base import Term

IRIS = ["https://e.org/a", "https://e.org/ab", "https://e.org/b", "https://e.org/robot/ari", "https://e.org/robot"]


def random_term(rng: random.Random) -> Term | None:
    kind = rng.randrange(6)
    if kind == 0:
        return None
    if kind == 1:
        return BlankNode(rng.choice(["b1", "b12", "b2"]))
    if kind in (2, 3):  # IRIs twice as often: the hubs a key begins with
        return NamedNode(rng.choice(IRIS))
    if kind == 4:
        return Literal(f"2026-03-10T09:0{rng.randrange(3)}:00Z", datatype=NamedNode(DATE_TIME))
    return Literal(rng.choice(["", "a", "ab", "b"]))


def test_heads_never_sort_against_their_keys() -> None:
    rng = random.Random(3)
    keys = {sort_key([random_term(rng) for _ in range(rng.randrange(1, 5))]) for _ in range(400)}
    for one, other in itertools.permutations(keys, 2):
        if head_of(one) < head_of(other):
            assert one < other, (one, other)


def test_a_head_ends_at_the_first_value_that_is_not_an_iri() -> None:
    time = Literal("2026-03-10T09:00:00Z", datatype=NamedNode(DATE_TIME))
    robot, human, message = NamedNode(IRIS[3]), NamedNode(IRIS[0]), NamedNode(IRIS[2])
    assert head_of(sort_key([time, message, human])) == sort_key([time])  # the timeline: its time
    assert head_of(sort_key([robot, human, time, message])) == sort_key([robot, human, time])  # conversations
    assert head_of(sort_key([robot, human])) == sort_key([robot, human])  # IRIs alone: the whole key
    assert SEPARATOR not in head_of(sort_key([None, robot]))  # unbound first: nothing after it
