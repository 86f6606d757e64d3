"""The rows of a SELECT DISTINCT answer are distinct whatever the store answered: Virtuoso 7 repeats solutions
of some SELECT DISTINCT queries (the emotion timeline's, after other graphs changed its statistics), and every
report row then showed twice. The answer below is such an answer, as SPARQL JSON."""

from __future__ import annotations

import json

from pyoxigraph import QueryResultsFormat, QuerySolutions, parse_query_results

from segb_server.backend.store.base import rows_of

ROW = {"emotion": {"type": "uri", "value": "https://e.org/emotion_1"}, "name": {"type": "literal", "value": "Juan"}}
OTHER = {"emotion": {"type": "uri", "value": "https://e.org/emotion_2"}}
ANSWER = json.dumps({"head": {"vars": ["emotion", "name"]}, "results": {"bindings": [ROW, ROW, OTHER, ROW]}})


def emotions(sparql: str) -> list[str]:
    answer = parse_query_results(ANSWER.encode(), QueryResultsFormat.JSON)
    assert isinstance(answer, QuerySolutions)
    return [row["emotion"].value for row in rows_of(sparql, answer).rows]


def test_a_distinct_select_drops_repeated_solutions_and_keeps_the_order() -> None:
    text = "PREFIX e: <https://e.org/>\n# a comment\nSELECT DISTINCT ?emotion ?name WHERE { ?emotion e:p ?name }"
    assert emotions(text) == ["https://e.org/emotion_1", "https://e.org/emotion_2"]


def test_a_plain_select_keeps_every_solution() -> None:
    text = "SELECT ?emotion ?name WHERE { { SELECT DISTINCT ?emotion ?name WHERE { ?emotion ?p ?name } } }"
    assert len(emotions(text)) == 4


def test_distinct_is_read_from_the_query_itself_never_from_its_comments_or_prefixes() -> None:
    header = "# title: Emotions\n# description: SELECT DISTINCT would be wrong here { really }\n"
    prefixes = "PREFIX rdfs: <http://www.w3.org/2000/01/rdf-schema#>\nPREFIX e: <https://e.org/>\n"
    assert len(emotions(header + prefixes + "SELECT ?emotion ?name WHERE { ?emotion e:p ?name }")) == 4
    keys = " ".join(f"<https://e.org/emotion_{index}>" for index in range(5000))  # a kept view's keys
    where = f"{{ VALUES ?emotion {{ {keys} }} ?emotion e:p ?name }}"
    kept = f"{header}{prefixes}select  distinct ?emotion ?name WHERE {where}"
    assert emotions(kept) == ["https://e.org/emotion_1", "https://e.org/emotion_2"]
