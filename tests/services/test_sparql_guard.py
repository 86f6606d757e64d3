"""The read-only guard: the four query forms pass, everything that writes or reaches outside the events graph
is refused with a reason, wherever it hides (prologue, lower case, escapes, prefixes)."""

from __future__ import annotations

from pathlib import Path

import pytest

from segb_server.backend.services.errors import InvalidQuery, PayloadTooLarge
from segb_server.backend.services.sparql.catalog import read_header
from segb_server.backend.services.sparql.guard import MAX_QUERY_BYTES, QueryTooLong, guard_query

EVENTS = "http://amor-segb/events"
SPARQL_DIR = Path(__file__).resolve().parents[2] / "sparql"


def rejection(query: str, events_graph: str | None = EVENTS) -> InvalidQuery:
    with pytest.raises(InvalidQuery) as caught:
        guard_query(query, events_graph)
    return caught.value


@pytest.mark.parametrize(
    ("query", "form"),
    [
        ("SELECT * WHERE { ?s ?p ?o } LIMIT 3", "select"),
        ("# who is there\nprefix foaf: <http://xmlns.com/foaf/0.1/>\nselect ?n { ?h foaf:firstName ?n }", "select"),
        ("ASK {}", "ask"),
        ("BASE <http://ex.org/>\nCONSTRUCT WHERE { ?s <p> ?o }", "construct"),
        ("DESCRIBE <http://ex.org/ari>", "describe"),
        ("PREFIX xsd: <http://www.w3.org/2001/XMLSchema#>\nSELECT (xsd:integer('4') AS ?n) {}", "select"),
        # Words that would be refused as keywords are harmless inside strings, IRIs, names and comments.
        ('SELECT ?insert { ?insert <http://ex.org/define> "DELETE SERVICE bif:x FROM <y>" } # DROP ALL', "select"),
    ],
)
def test_read_queries_pass_and_report_their_form(query: str, form: str) -> None:
    assert guard_query(query, EVENTS).form == form
    assert guard_query(query, EVENTS).text == query


def test_the_project_report_and_graph_queries_pass() -> None:
    files = [path for path in sorted(SPARQL_DIR.rglob("*.rq")) if "# same-as:" not in path.read_text()]
    assert files
    for path in files:
        # As the catalog loads it: each rule of reading (`%rule(…)`) expanded
        assert guard_query(read_header(path.read_text()).text, EVENTS).form in ("select", "construct"), path


FORBIDDEN = [
    # (query, reason, text the message must contain)
    ("INSERT DATA {<a:x> <a:y> <a:z>}", "update", "SPARQL Update (INSERT) is not allowed"),
    ("DELETE WHERE {?s ?p ?o}", "update", "SPARQL Update (DELETE)"),
    ("prefix x: <http://x/> insert data { x:a x:b x:c }", "update", "SPARQL Update (INSERT)"),
    ("# comment\nBASE <http://x/>\nPREFIX : <http://x/>\n  clear all", "update", "SPARQL Update (CLEAR)"),
    ("LOAD <http://example.org/>", "update", "(LOAD)"),
    ("DROP GRAPH <http://amor-segb/events>", "update", "(DROP)"),
    ("CREATE GRAPH <http://ex.org/g>", "update", "(CREATE)"),
    ("WITH <http://ex.org/g> DELETE { ?s ?p ?o } WHERE { ?s ?p ?o }", "update", "(WITH)"),
    ("INSERT INTO GRAPH <http://ex.org/g> { <a:x> <a:y> <a:z> }", "update", "(INSERT)"),  # Virtuoso's own form
    ("SELECT * {} ; INSERT DATA {<a:x> <a:y> <a:z>}", "syntax", "line 1, column 13"),
    ("select * where { SERVICE <http://example.org/sparql> { ?s ?p ?o } }", "service", "SERVICE clauses"),
    ("select (bif:sprintf('%s','x') as ?x) {}", "virtuoso_extension", "'bif:sprintf'"),
    ("PREFIX b: <bif:> SELECT (b:sprintf('%s', 'x') AS ?x) {}", "virtuoso_extension", "bif:"),
    ("SELECT * { ?s ?p ?o . ?o bif:contains 'robot' }", "virtuoso_extension", "'bif:contains'"),
    ("SELECT * { ?s <bif:contains> 'robot' }", "virtuoso_extension", "bif:contains"),
    ("SELECT (sql:my_procedure() AS ?x) {}", "virtuoso_extension", "'sql:my_procedure'"),
    ("SELECT (\\u0062if:sprintf('x') AS ?x) {}", "virtuoso_extension", "'bif:sprintf'"),
    ("PREFIX v: <http://www.openlinksw.com/schemas/virtrdf#> SELECT * { ?s v:p ?o }", "virtuoso_extension", ""),
    ("define input:default-graph-uri <http://x> select * {?s ?p ?o}", "virtuoso_pragma", "DEFINE pragmas"),
    ("# Virtuoso\nDEFINE sql:signal-void-variables 1\nSELECT * { ?s ?p ?o }", "virtuoso_pragma", "line 2, column 1"),
    ('define get:soft "replace" SELECT * FROM <http://example.org/> { ?s ?p ?o }', "virtuoso_pragma", "not allowed"),
    ("PREFIX ex: <http://ex.org/> SELECT * { ?s ?p ?o FILTER(ex:f(?o)) }", "extension_function", "<http://ex.org/f>"),
    ("SELECT * FROM <http://ex.org/other> { ?s ?p ?o }", "dataset", "FROM <http://ex.org/other> is not allowed"),
    ("SELECT * FROM NAMED <http://amor-segb/events> { ?s ?p ?o }", "dataset", "FROM NAMED"),
    ("SELECT * { GRAPH ?g { ?s ?p ?o } }", "graph", "GRAPH patterns"),
    ("SELECT * { ?s foaf:name ?o }", "undeclared_prefix", "'foaf:' is not declared"),
    ("  \n ", "empty", "empty"),
    # rdflib parses these as an update of no operations: they are empty, not updates.
    ("# what robots said\n# (nothing yet)\n", "empty", "only comments"),
    ("PREFIX schema: <http://schema.org/>  # the query is still to write", "empty", "PREFIX declarations"),
]


@pytest.mark.parametrize(
    ("query", "reason", "fragment"), FORBIDDEN, ids=[f"{r}-{i}" for i, (_, r, _) in enumerate(FORBIDDEN)]
)
def test_forbidden_queries_are_rejected_with_their_reason(query: str, reason: str, fragment: str) -> None:
    error = rejection(query)
    assert error.details["reason"] == reason
    assert fragment in error.message


def test_an_update_reports_its_kind_and_a_query_its_form() -> None:
    assert rejection("INSERT DATA {<a:x> <a:y> <a:z>}").details["query_kind"] == "update"
    assert rejection("SELECT * { GRAPH ?g { ?s ?p ?o } }").details["query_kind"] == "select"
    assert rejection("HELLO").details["query_kind"] == "unknown"


def test_a_syntax_error_gives_line_and_column() -> None:
    error = rejection("PREFIX ex: <http://ex.org/>\nSELECT ?s WHERE {\n  ?s ex:p ?o .\n  FILTER(?o > )\n}")
    assert error.details == {"reason": "syntax", "line": 4, "column": 3, "query_kind": "select"}
    assert error.message == "Invalid SPARQL syntax at line 4, column 3: unexpected 'FILTER'."
    assert rejection("SELECT * WHERE { ?s ?p ?o ").message.endswith("unexpected end of the query.")


def test_from_the_events_graph_is_dropped_and_other_text_kept() -> None:
    query = f'PREFIX e: <http://amor-segb/>\nSELECT ?s FROM <{EVENTS}>\nFROM e:events WHERE {{ ?s ?p "FROM <x>" }}'
    checked = guard_query(query, EVENTS)
    assert "FROM" not in checked.text.replace('"FROM <x>"', "")
    assert checked.text.endswith('WHERE { ?s ?p "FROM <x>" }')
    assert len(checked.text) == len(query)  # blanked, so positions in store errors still match the user's text
    # Without a known events graph, no FROM can be vouched for.
    assert rejection(f"SELECT * FROM <{EVENTS}> {{ ?s ?p ?o }}", events_graph=None).details["reason"] == "dataset"


def test_the_most_serious_problem_is_reported_first() -> None:
    query = "SELECT * { GRAPH ?g { ?s ?p ?o } SERVICE <http://ex.org/sparql> { ?s ?p ?o } BIND(bif:now() AS ?t) }"
    assert rejection(query).details["reason"] == "virtuoso_extension"


def test_too_long_a_query_is_a_413() -> None:
    query = "SELECT * { ?s ?p ?o }" + " " * MAX_QUERY_BYTES
    with pytest.raises(QueryTooLong) as caught:
        guard_query(query)
    assert isinstance(caught.value, PayloadTooLarge)
    assert caught.value.details["reason"] == "too_long"


def test_nesting_beyond_the_parser_is_refused_not_a_crash() -> None:
    query = "SELECT * { FILTER(" + "(" * 60 + "1" + ")" * 60 + ") }"
    assert rejection(query).details["reason"] == "too_deep"
