"""Bodies that once made the ingest answer 500 are refused with a 4xx naming the problem, and leave the
server answering: JSON nested 100,000 deep (a RecursionError), a field given twice (the last one won), an
unpaired surrogate in any text field, a literal or IRI over the parser's 16 MiB buffer."""

from __future__ import annotations

import pytest

from tests.support.in_process import InProcess

JSON = {"Content-Type": "application/json"}
HUGE = 17 * 1024 * 1024
CASES = {
    "json nested 100,000 deep": (
        b'{"ttl_content": ' + b"[" * 100_000 + b"]" * 100_000 + b"}",
        JSON,
        422,
        "nests arrays or objects too deeply",
    ),
    "ttl_content given twice": (
        b'{"ttl_content": "<https://e.org/a> <https://e.org/p> 1 .", '
        b'"ttl_content": "<https://e.org/b> <https://e.org/p> 2 ."}',
        JSON,
        422,
        "gives 'ttl_content' more than once",
    ),
    "unpaired surrogate in user": (
        b'{"ttl_content": "<https://e.org/u> <https://e.org/p> \\"x\\" .", "user": "\\ud800"}',
        JSON,
        422,
        "'user' holds an unpaired surrogate",
    ),
    "unpaired surrogate in ttl_content": (
        b'{"ttl_content": "<https://e.org/u> <https://e.org/p> \\"\\udfff\\" ."}',
        JSON,
        422,
        "'ttl_content' holds an unpaired surrogate",
    ),
    "literal over 16 MiB": (
        b'<https://e.org/a> <https://e.org/p> "' + b"x" * HUGE + b'" .',
        {"Content-Type": "application/n-triples"},
        413,
        "too long for the RDF parser",
    ),
    "iri over 16 MiB": (
        b"<https://e.org/" + b"x" * HUGE + b"> <https://e.org/p> 1 .",
        {"Content-Type": "text/turtle"},
        413,
        "too long for the RDF parser",
    ),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_a_hostile_body_is_a_4xx_naming_the_problem(memory_api: InProcess, case: str) -> None:
    body, headers, status, detail = CASES[case]
    answer = memory_api.post("/ttl", content=body, headers=headers)
    assert (answer.status_code, detail in answer.json()["detail"]) == (status, True), answer.text[:300]
    assert memory_api.get("/events", headers={"Accept": "application/n-triples"}).content == b""
    assert memory_api.get("/healthz/ready").status_code == 200


@pytest.mark.parametrize("path", ["/humans/erase", "/shared-context/resolve", "/shared-context/review/x/accept"])
def test_a_body_that_is_not_json_is_named_so_with_where_the_parser_stopped(memory_api: InProcess, path: str) -> None:
    """The routes whose body FastAPI reads: its own words are only "JSON decode error"."""
    answer = memory_api.post(path, content=b'{"iri": "https://e.org/h", oops}', headers=JSON)
    assert answer.status_code == 422
    body = answer.json()
    assert body["error"] == "invalid_request"
    assert "the body is not JSON: Expecting property name enclosed in double quotes at character 27" in body["message"]
