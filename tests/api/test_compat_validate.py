"""POST /ttl/validate through the whole app in process, with the reference backend's request and report: what the ingest
would refuse (found by the ingest's own parser, so the two always agree), the reference's rules on the robots'
vocabulary, the ingest's body limits, and nothing ever written."""

from __future__ import annotations

import gzip
from collections.abc import Iterator

import httpx
import pytest
from pyoxigraph import RdfFormat, parse

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from segb_server.backend.services.ingest.validation import MAX_ISSUES
from segb_server.backend.store.base import Store
from segb_server.backend.store.sparql_http import SparqlHttpStore
from tests.conftest import FIXTURES, make_settings
from tests.support.in_process import InProcess, Server, http
from tests.support.net import free_port

REPORT_KEYS = {"valid", "syntax_ok", "semantic_ok", "triple_count", "issues"}
ISSUE_KEYS = {"severity", "code", "message", "focus_node", "predicate", "value"}
PREFIXES = (
    "@prefix prov: <http://www.w3.org/ns/prov#> .\n"
    "@prefix onyx: <http://www.gsi.upm.es/ontologies/onyx/ns#> .\n"
    "@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n"
    "@prefix ex: <https://example.org/> .\n"
)
GOOD = PREFIXES + "ex:ari a prov:Agent ;\n    prov:wasAssociatedWith ex:maria .\nex:maria a prov:Agent .\n"


def validate(server: Server, ttl: str | None = None, **kwargs: object) -> httpx.Response:
    if ttl is not None:
        kwargs["json"] = {"ttl_content": ttl}  # the reference UI's request
    return http(server, "POST", "/ttl/validate", **kwargs)


def report(server: Server, ttl: str) -> dict[str, object]:
    answer = validate(server, ttl)
    assert answer.status_code == 200, answer.text
    return answer.json()


def test_a_robots_document_validates_in_the_reference_shape_and_nothing_is_written(
    api: InProcess, store: Store
) -> None:
    turtle = (FIXTURES / "reference_uc01.ttl").read_text()
    body = report(api.client, turtle)
    assert set(body) >= REPORT_KEYS
    assert (body["valid"], body["syntax_ok"], body["semantic_ok"], body["ingest_ok"]) == (True, True, True, True)
    assert body["triple_count"] == len(list(parse(turtle.encode(), RdfFormat.TURTLE))) == 268
    assert body["issues"] == []
    assert store.count() == 0


@pytest.fixture
def limited(memory_store: Store) -> Iterator[InProcess]:
    """Small limits, so every refusal of the ingest is cheap to reach."""
    settings = make_settings(max_body_bytes=4096, max_decompressed_bytes=8192, max_triples_per_post=5)
    with InProcess(create_app(settings, store=memory_store)) as server:
        yield server


# name → (Turtle, the issue code, its line and column, syntax_ok, what POST /ttl answers)
REFUSED = {
    "syntax error": (PREFIXES + "ex:a ex:b\n  ex:c ex:d .", "TTL_SYNTAX_ERROR", 6, 8, False, 400),
    "unterminated literal": (PREFIXES + 'ex:a ex:b "hello\n', "TTL_SYNTAX_ERROR", 5, 11, False, 400),
    "relative iri": ("<a> <https://example.org/b> <https://example.org/c> .", "TTL_SYNTAX_ERROR", 1, 1, False, 400),
    "undeclared prefix": ("ex:a ex:b ex:c .", "TTL_SYNTAX_ERROR", 1, 1, False, 400),
    "triple term": (
        PREFIXES + "ex:a ex:b <<( ex:a ex:b ex:c )>> .",
        "INGEST_REFUSED",
        None,
        None,
        True,
        400,
    ),
    "too many triples": (
        PREFIXES + "".join(f"ex:s{i} ex:p {i} .\n" for i in range(6)),
        "INGEST_TOO_LARGE",
        None,
        None,
        True,
        413,
    ),
    "blank ttl_content": ("  \n", "SEM_EMPTY_GRAPH", None, None, True, 422),
}


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_what_the_ingest_refuses_is_found_with_its_position_and_the_ingest_agrees(
    limited: InProcess, name: str
) -> None:
    turtle, code, line, column, syntax_ok, ingest_status = REFUSED[name]
    body = report(limited.client, turtle)
    assert (body["valid"], body["semantic_ok"], body["ingest_ok"], body["syntax_ok"]) == (
        False,
        False,
        False,
        syntax_ok,
    )
    assert body["triple_count"] == 0
    [issue] = body["issues"]
    assert set(issue) >= ISSUE_KEYS
    assert (issue["severity"], issue["code"], issue["line"], issue["column"]) == ("error", code, line, column)

    posted = limited.post("/ttl", json={"ttl_content": turtle})
    assert posted.status_code == ingest_status, posted.text
    if line is not None:  # the same position as the ingest's own refusal
        assert (posted.json()["line"], posted.json()["column"]) == (line, column)
    if name == "relative iri":
        assert "relative IRIs are not accepted" in issue["message"]


def test_what_the_ingest_takes_is_ingest_ok_even_where_the_reference_rules_object(limited: InProcess) -> None:
    prefixes_only = report(limited.client, PREFIXES)
    assert (prefixes_only["valid"], prefixes_only["ingest_ok"]) == (False, True)  # the reference: an empty graph
    assert [issue["code"] for issue in prefixes_only["issues"]] == ["SEM_EMPTY_GRAPH"]
    good = report(limited.client, GOOD)
    assert (good["valid"], good["ingest_ok"], good["triple_count"], good["issues"]) == (True, True, 3, [])
    for turtle in (PREFIXES, GOOD):
        assert limited.post("/ttl", json={"ttl_content": turtle}).status_code == 201


BROKEN_RULES = PREFIXES + (
    'ex:run a "Activity" ;\n'
    '    prov:used "the camera" ;\n'
    '    prov:startedAtTime "2026-03-10T09:00:00Z" ;\n'
    '    prov:endedAtTime "yesterday"^^xsd:dateTime ;\n'
    "    prov:generatedAtTime ex:noon .\n"
    'ex:emotion onyx:hasEmotionIntensity "NaN"^^xsd:double , 1.5 , "0.5" , "high" ;\n'
    '    onyx:hasEmotionCategory "joy" .\n'
)


def test_the_reference_rules_on_the_robots_vocabulary(memory_api: InProcess) -> None:
    body = report(memory_api.client, BROKEN_RULES)
    assert (body["valid"], body["semantic_ok"], body["syntax_ok"], body["ingest_ok"]) == (False, False, True, True)
    assert body["triple_count"] == 10
    ex, prov, onyx = "https://example.org/", "http://www.w3.org/ns/prov#", "http://www.gsi.upm.es/ontologies/onyx/ns#"
    found = [(i["severity"], i["code"], i["focus_node"], i["predicate"], i["value"]) for i in body["issues"]]
    assert found == [
        ("error", "SEM_RDF_TYPE_LITERAL", ex + "run", "http://www.w3.org/1999/02/22-rdf-syntax-ns#type", "Activity"),
        ("error", "SEM_OBJECT_PROPERTY_LITERAL", ex + "run", prov + "used", "the camera"),
        ("error", "SEM_DATETIME_WRONG_DATATYPE", ex + "run", prov + "startedAtTime", "2026-03-10T09:00:00Z"),
        ("error", "SEM_DATETIME_INVALID_LEXICAL", ex + "run", prov + "endedAtTime", "yesterday"),
        ("error", "SEM_DATETIME_NOT_LITERAL", ex + "run", prov + "generatedAtTime", ex + "noon"),
        # NaN is refused as not a number (the reference crashed on it with a 500); a plain "0.5" passes.
        ("error", "SEM_INTENSITY_NOT_NUMERIC", ex + "emotion", onyx + "hasEmotionIntensity", "NaN"),
        ("error", "SEM_INTENSITY_OUT_OF_RANGE", ex + "emotion", onyx + "hasEmotionIntensity", "1.5"),
        ("error", "SEM_INTENSITY_NOT_NUMERIC", ex + "emotion", onyx + "hasEmotionIntensity", "high"),
        ("error", "SEM_EMOTION_CATEGORY_LITERAL", ex + "emotion", onyx + "hasEmotionCategory", "joy"),
        ("warning", "SEM_SUBJECT_WITHOUT_TYPE", ex + "emotion", None, None),
    ]
    assert (body["error_count"], body["warning_count"], body["issues_truncated"]) == (9, 1, False)


def test_warnings_alone_keep_a_document_valid(memory_api: InProcess) -> None:
    body = report(
        memory_api.client,
        PREFIXES
        + 'ex:e onyx:hasEmotionIntensity 0.25 ; prov:startedAtTime "2026-03-10T09:00:00.5+01:00"^^xsd:dateTime .',
    )
    assert (body["valid"], body["semantic_ok"]) == (True, True)
    assert [(issue["severity"], issue["code"]) for issue in body["issues"]] == [("warning", "SEM_SUBJECT_WITHOUT_TYPE")]


def test_blank_nodes_are_named_as_in_the_document(memory_api: InProcess) -> None:
    body = report(memory_api.client, PREFIXES + '[] a prov:Activity ; prov:used "a literal" .')
    [issue] = body["issues"]
    assert issue["code"] == "SEM_OBJECT_PROPERTY_LITERAL" and issue["focus_node"].startswith("_:")


def test_a_token_with_write_scopes_gets_the_verdict_the_ingest_gives_it(memory_store: Store) -> None:
    secret = "a-test-secret-that-is-long-enough-for-hs256"
    token = mint_token(secret, username="ari-admin", roles=["admin"], scopes=["https://example.org/ari"]).token
    headers = {"Authorization": f"Bearer {token}"}
    with InProcess(create_app(make_settings(secret_key=secret), store=memory_store)) as server:
        inside = validate(server.client, PREFIXES + "ex:ari a prov:Agent .", headers=headers)
        outside = validate(server.client, GOOD, headers=headers)
        posted = server.post("/ttl", json={"ttl_content": GOOD}, headers=headers)
        logger_token = mint_token(secret, username="ari", roles=["logger"]).token
        refused = validate(server.client, GOOD, headers={"Authorization": f"Bearer {logger_token}"})
    assert (inside.json()["valid"], inside.json()["ingest_ok"]) == (True, True)
    assert (outside.json()["ingest_ok"], [issue["code"] for issue in outside.json()["issues"]]) == (
        False,
        ["INGEST_OUT_OF_SCOPE"],
    )
    assert "https://example.org/maria" in outside.json()["issues"][0]["message"]
    assert posted.status_code == 403
    assert refused.status_code == 403  # the reference's role: admin


def test_the_issue_list_is_bounded_but_the_counts_are_exact(memory_api: InProcess) -> None:
    turtle = PREFIXES + "".join(
        f"ex:e{i} a ex:Emotion ; onyx:hasEmotionIntensity 7 .\n" for i in range(MAX_ISSUES + 200)
    )
    body = report(memory_api.client, turtle)
    assert len(body["issues"]) == MAX_ISSUES
    assert (body["error_count"], body["issues_truncated"], body["valid"]) == (MAX_ISSUES + 200, True, False)


REQUESTS_THE_INGEST_REFUSES = {
    "body over MAX_BODY_BYTES": ({"json": {"ttl_content": GOOD + "#" * 5000}}, 413, "MAX_BODY_BYTES"),
    "gzip over MAX_DECOMPRESSED_BYTES": (
        {
            "content": gzip.compress(b"#" * 100_000),
            "headers": {"Content-Type": "text/turtle", "Content-Encoding": "gzip"},
        },
        413,
        "MAX_DECOMPRESSED_BYTES",
    ),
    "another content type": ({"content": GOOD.encode(), "headers": {"Content-Type": "text/plain"}}, 415, "text/plain"),
    "not json": ({"content": b"{nope", "headers": {"Content-Type": "application/json"}}, 422, "not valid JSON"),
    "no ttl_content": ({"json": {"user": "ari"}}, 422, "ttl_content"),
    "ttl_content not a string": ({"json": {"ttl_content": ["a"]}}, 422, "ttl_content"),
}


@pytest.mark.parametrize("name", sorted(REQUESTS_THE_INGEST_REFUSES))
def test_requests_the_ingest_refuses_get_the_same_status(limited: InProcess, name: str) -> None:
    request, status, named = REQUESTS_THE_INGEST_REFUSES[name]
    checked = validate(limited.client, **request)
    posted = limited.post("/ttl", **request)
    assert (checked.status_code, posted.status_code) == (status, status), checked.text
    assert named in checked.json()["detail"] and checked.json()["status"] == status


def test_raw_and_gzipped_bodies_are_read_as_the_ingest_reads_them(memory_api: InProcess) -> None:
    raw = validate(memory_api.client, content=GOOD.encode(), headers={"Content-Type": "text/turtle"})
    zipped = validate(
        memory_api.client,
        content=gzip.compress(GOOD.encode()),
        headers={"Content-Type": "text/turtle", "Content-Encoding": "gzip"},
    )
    ntriples = validate(
        memory_api.client,
        content=b"<https://example.org/a> <https://example.org/b> <https://example.org/c> .\n",
        headers={"Content-Type": "application/n-triples"},
    )
    assert [answer.json()["triple_count"] for answer in (raw, zipped, ntriples)] == [3, 3, 1]


def unreachable_store() -> SparqlHttpStore:
    """A store whose endpoint nothing listens on: every call to it fails as a store that is down."""
    endpoint = f"http://127.0.0.1:{free_port()}/sparql"
    return SparqlHttpStore(
        query_endpoint=endpoint, update_endpoint=endpoint, graph_uri="http://amor-segb/events", timeout_seconds=2
    )


def test_validation_needs_no_store() -> None:
    store = unreachable_store()
    with InProcess(create_app(make_settings(store="sparql"), store=store)) as server:
        checked = validate(server.client, GOOD)
        posted = server.post("/ttl", json={"ttl_content": GOOD})
    store.close()
    assert (checked.status_code, checked.json()["valid"]) == (200, True)
    assert posted.status_code == 503
