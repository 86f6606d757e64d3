"""/sparql's CSV and TSV answers, and the workbench's CSV download relayed from it, are opened in spreadsheets: a
robot's text that a spreadsheet would run as a formula (`=HYPERLINK(…)`) is written as text there, with the leading
apostrophe of the reports' downloads (services/csv_cells.py); numbers keep their sign and JSON keeps the text."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator

import pytest
from pyoxigraph import Literal, NamedNode

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.in_process import UiOverApi

FORMULA = '=HYPERLINK("http://evil.example/","click")'
AT_FORMULA = "@SUM(1+1)*cmd|' /C calc'!A0"
NAME = "http://xmlns.com/foaf/0.1/firstName"
VALENCE = "https://example.org/valence"
XSD_DECIMAL = NamedNode("http://www.w3.org/2001/XMLSchema#decimal")
TURTLE = f"""
<https://example.org/eve> <{NAME}> {Literal(FORMULA)} ; <{VALENCE}> {Literal("-0.5", datatype=XSD_DECIMAL)} .
<https://example.org/mallory> <{NAME}> {Literal(AT_FORMULA, language="en")} ; <{VALENCE}> {Literal("-3")} .
"""
QUERY = f"SELECT ?who ?name ?valence WHERE {{ ?who <{NAME}> ?name ; <{VALENCE}> ?valence }} ORDER BY ?who"


@pytest.fixture(scope="module")
def served() -> Iterator[UiOverApi]:
    with UiOverApi(create_app(make_settings()), make_settings()) as server:
        posted = server.api.post("/ttl", content=TURTLE, headers={"Content-Type": "text/turtle"})
        assert posted.status_code == 201, posted.text
        yield server


def csv_rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text, newline="")))


def test_a_csv_answer_writes_a_formula_as_text_and_keeps_numbers(served: UiOverApi) -> None:
    answer = served.api.get("/sparql", params={"query": QUERY, "format": "csv"})
    assert answer.status_code == 200 and answer.headers["content-type"].startswith("text/csv")
    assert csv_rows(answer.text) == [
        ["who", "name", "valence"],
        ["https://example.org/eve", "'" + FORMULA, "-0.5"],
        ["https://example.org/mallory", "'" + AT_FORMULA, "-3"],
    ]
    assert answer.text.endswith("\r\n")  # SPARQL's CSV keeps its CRLF line ends


def test_a_csv_answer_chosen_by_accept_and_posted_is_written_the_same(served: UiOverApi) -> None:
    answer = served.api.post("/sparql", data={"query": QUERY}, headers={"Accept": "text/csv"})
    assert answer.status_code == 200
    assert csv_rows(answer.text)[1][1] == "'" + FORMULA


def test_a_tsv_answer_writes_the_formula_as_text_inside_its_literal(served: UiOverApi) -> None:
    answer = served.api.get("/sparql", params={"query": QUERY, "format": "tsv"})
    assert answer.status_code == 200
    lines = [line.split("\t") for line in answer.text.splitlines()]
    assert lines[0] == ["?who", "?name", "?valence"]
    assert lines[1][1] == str(Literal("'" + FORMULA))
    assert lines[1][2] in ("-0.5", str(Literal("-0.5", datatype=XSD_DECIMAL)))  # a number, as sent
    assert lines[2][1] == str(Literal("'" + AT_FORMULA, language="en"))
    assert lines[2][2] == str(Literal("-3"))  # text that reads as a number is no formula


def test_the_json_answer_keeps_the_text_as_sent(served: UiOverApi) -> None:
    rows = served.api.get("/sparql", params={"query": QUERY, "format": "json"}).json()["results"]["bindings"]
    assert [row["name"]["value"] for row in rows] == [FORMULA, AT_FORMULA]


def test_the_workbench_csv_download_writes_the_formula_as_text(served: UiOverApi) -> None:
    download = served.get("/query/download.csv", params={"query": QUERY})
    assert download.status_code == 200, download.text
    assert download.headers["content-disposition"] == 'attachment; filename="query.csv"'
    rows = csv_rows(download.text)
    assert [row[1] for row in rows[1:]] == ["'" + FORMULA, "'" + AT_FORMULA]
    assert not any(cell.startswith(("=", "@", "+")) for row in rows for cell in row)
