"""IRIs in a table's sort keys are written without their namespaces (`key_namespaces.py`), and date-times as
10 digits: the keys must still sort as ORDER BY does, and as the keys written whole did."""

from __future__ import annotations

import itertools
import random

from pyoxigraph import BlankNode, Literal, NamedNode

from segb_server.backend.services.views.kept_queries.aggregate_values import _decoded
from segb_server.backend.services.views.kept_queries.encoding import DATE_TIME, instant_micros, sort_key
from segb_server.backend.services.views.kept_queries.key_namespaces import Namespaces, order_digits
from segb_server.backend.services.views.kept_queries.layout import head_of
from segb_server.backend.store.base import Term

ROBOTS = "https://example.org/segb/robots/"
# Namespaces, their extensions, IRIs before, between and after them, prefixes of them, and one equal to one
IRIS = [
    ROBOTS,
    ROBOTS + "ari/v1/",
    ROBOTS + "ari/v1/robot_ari",
    ROBOTS + "ari/v1/human_visitor_1",
    ROBOTS + "ari/v1/human_visitor_10",
    ROBOTS + "ari/v1/human_visitor_2",
    ROBOTS + "ari/v1",
    ROBOTS + "ari/v10/x",
    ROBOTS + "ari/v0/x",
    ROBOTS + "ari/",
    ROBOTS + "aria",
    ROBOTS + "b",
    ROBOTS[:-1],
    "https://example.org/segb/",
    "https://example.org/segb/robots~",
    "https://gsi.upm.es/segb/shared-events/human_utterance_7",
    "https://gsi.upm.es/segb/shared-events/human_utterance_7#observation-1",
    "urn:x",
    "a:",
    "https:",
]
NAMESPACES = Namespaces.made_from(
    [ROBOTS + "ari/v1/robot_ari", ROBOTS + "x", "https://gsi.upm.es/segb/shared-events/e"]
)
TIMES = ["2026-03-10T09:00:00Z", "2026-03-10T09:00:00.5Z", "2026-03-10T10:00:00+02:00", "0001-01-01T00:00:00Z",
         "9999-12-31T23:59:59.999999Z", "2026-03-10T09:00:00"]  # fmt: skip


def random_term(rng: random.Random) -> Term | None:
    kind = rng.randrange(6)
    if kind == 0:
        return None
    if kind == 1:
        return BlankNode(rng.choice(["b1", "b12"]))
    if kind in (2, 3):
        return NamedNode(rng.choice(IRIS)) if rng.random() < 0.9 else NamedNode(ROBOTS + str(rng.randrange(99)))
    if kind == 4:
        return Literal(rng.choice(TIMES), datatype=NamedNode(DATE_TIME))
    return Literal(rng.choice(["", "a", "ab"]))


def test_namespaces_are_the_long_ones_of_the_iris_given_sorted() -> None:
    assert NAMESPACES.entries == (ROBOTS, ROBOTS + "ari/v1/", "https://gsi.upm.es/segb/shared-events/")


def test_keys_written_with_namespaces_sort_as_keys_written_whole() -> None:
    rng = random.Random(5)
    tuples = [[random_term(rng) for _ in range(rng.randrange(1, 4))] for _ in range(500)]
    for one, other in itertools.combinations(tuples, 2):
        whole = (sort_key(one) > sort_key(other)) - (sort_key(one) < sort_key(other))
        short = (sort_key(one, NAMESPACES) > sort_key(other, NAMESPACES)) - (
            sort_key(one, NAMESPACES) < sort_key(other, NAMESPACES)
        )
        assert whole == short, (one, other)


def test_keys_written_whole_sort_as_the_values_do() -> None:
    iris = sorted(IRIS)
    assert sorted(iris, key=lambda iri: sort_key([NamedNode(iri)], NAMESPACES)) == iris
    times = [Literal(text, datatype=NamedNode(DATE_TIME)) for text in TIMES[:5]]
    ordered = sorted(times, key=lambda term: instant_micros(term) or 0)
    assert [term.value for term in ordered] == [TIMES[3], TIMES[2], TIMES[0], TIMES[1], TIMES[4]]
    assert sorted(times, key=lambda term: sort_key([term])) == ordered


def test_a_key_is_shorter_and_its_head_still_ends_at_its_time() -> None:
    robot, human = NamedNode(ROBOTS + "ari/v1/robot_ari"), NamedNode(ROBOTS + "ari/v1/human_visitor_12345")
    time = Literal("2026-03-10T09:00:05Z", datatype=NamedNode(DATE_TIME))
    message = NamedNode(ROBOTS + "ari/v1/message_user_12345")
    key = sort_key([robot, human, time, message], NAMESPACES)
    assert len(key) < len(sort_key([robot, human, time, message])) / 2
    assert head_of(key) == sort_key([robot, human, time], NAMESPACES)
    assert len(sort_key([time])) == 11


def test_a_date_time_part_reads_back_as_its_instant() -> None:
    for text, expected in [("2026-03-10T10:00:05.25+02:00", "2026-03-10T08:00:05.25Z"),
                           ("0001-01-01T00:00:00Z", "0001-01-01T00:00:00Z")]:  # fmt: skip
        assert _decoded(sort_key([Literal(text, datatype=NamedNode(DATE_TIME))])) == expected
    assert _decoded(sort_key([NamedNode(ROBOTS + "x")])) == ROBOTS + "x"  # aggregates' keys: written whole


def test_order_digits_are_fixed_width_and_sort_as_their_numbers() -> None:
    numbers = [0, 1, 63, 64, 4095, 10**17, 2**60 - 1]
    written = [order_digits(number, 10) for number in numbers]
    assert all(len(text) == 10 for text in written)
    assert sorted(written) == written
