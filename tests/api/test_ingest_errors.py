"""Bad input to POST /ttl: a clear 4xx naming the problem, and the store left exactly as it was."""

from __future__ import annotations

import gzip
import json
from collections.abc import Iterator

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.services.test_skolem import TWO_CYCLES
from tests.support.in_process import InProcess

GOOD = '@prefix ex: <https://ex.org/> .\nex:ari a ex:Robot ;\n    ex:name "ARI" .\n'


def small_limits(store: Store) -> InProcess:
    """The API with small limits on `store`, which holds GOOD (two triples) once entered."""
    settings = make_settings(max_body_bytes=4096, max_decompressed_bytes=8192, max_triples_per_post=50)
    return InProcess(create_app(settings, store=store))


@pytest.fixture
def small_limits_api(memory_store: Store) -> Iterator[InProcess]:
    with small_limits(memory_store) as server:
        server.post("/ttl", json={"ttl_content": GOOD}).raise_for_status()
        yield server


@pytest.fixture(scope="module")
def refusing_api() -> Iterator[tuple[InProcess, Store]]:
    """One server for every bad input: each is refused and writes nothing, so each finds the store as it was."""
    store = OxigraphStore("http://amor-segb/events")
    with small_limits(store) as server:
        server.post("/ttl", json={"ttl_content": GOOD}).raise_for_status()
        yield server, store
    store.close()


def post(server: InProcess, **kwargs: object) -> httpx.Response:
    return server.post("/ttl", **kwargs)  # type: ignore[arg-type]


def many_triples(count: int) -> str:
    return "".join(f'<https://ex.org/s{i}> <https://ex.org/p> "{i}" .\n' for i in range(count))


BAD_INPUTS = {
    "malformed turtle": (
        {"json": {"ttl_content": GOOD + 'ex:maria ex:says "hello\n', "user": "x"}},
        400,
        "Invalid Turtle at line 4, column",
    ),
    "turtle missing a dot": (
        {"json": {"ttl_content": GOOD + "ex:a ex:b ex:c\nex:d ex:e ex:f ."}},
        400,
        "line 5, column 1",
    ),
    "relative iri": ({"json": {"ttl_content": "<a> <b> <c> ."}}, 400, "relative IRIs are not accepted"),
    "malformed n-triples": (
        {"content": b"<https://ex.org/a> <https://ex.org/b> .\n", "headers": {"Content-Type": "application/n-triples"}},
        400,
        "Invalid N-Triples at line 1",
    ),
    "empty ttl_content": ({"json": {"ttl_content": "   \n"}}, 422, "'ttl_content' is empty"),
    "empty raw body": ({"content": b"", "headers": {"Content-Type": "text/turtle"}}, 422, "body is empty"),
    "missing ttl_content": ({"json": {"user": "ari"}}, 422, "ttl_content: Field required"),
    "ttl_content not a string": ({"json": {"ttl_content": 42}}, 422, "ttl_content: Input should be a valid string"),
    "not json": (
        {"content": b"{not json", "headers": {"Content-Type": "application/json"}},
        422,
        "not valid JSON",
    ),
    "wrong content type": ({"content": GOOD.encode(), "headers": {"Content-Type": "text/html"}}, 415, "text/html"),
    "no content type": ({"content": GOOD.encode()}, 415, "no Content-Type"),
    "unknown encoding": (
        {"content": GOOD.encode(), "headers": {"Content-Type": "text/turtle", "Content-Encoding": "br"}},
        415,
        "Content-Encoding 'br'",
    ),
    "body over the limit": ({"json": {"ttl_content": GOOD + "#" * 5000}}, 413, "MAX_BODY_BYTES"),
    "gzip bomb": (
        {
            "content": gzip.compress(b"#" * 1_000_000),
            "headers": {"Content-Type": "text/turtle", "Content-Encoding": "gzip"},
        },
        413,
        "MAX_DECOMPRESSED_BYTES",
    ),
    "not gzip": (
        {"content": b"not gzip at all", "headers": {"Content-Type": "text/turtle", "Content-Encoding": "gzip"}},
        422,
        "cannot be decompressed",
    ),
    "truncated gzip": (
        {
            "content": gzip.compress(GOOD.encode())[:-12],
            "headers": {"Content-Type": "text/turtle", "Content-Encoding": "gzip"},
        },
        422,
        "truncated",
    ),
    "too many triples": (
        {
            "content": gzip.compress(many_triples(51).encode()),
            "headers": {"Content-Type": "application/n-triples", "Content-Encoding": "gzip"},
        },
        413,
        "more than 50 triples",
    ),
}


@pytest.mark.parametrize("case", BAD_INPUTS, ids=list(BAD_INPUTS))
def test_bad_input_is_refused_and_nothing_is_written(refusing_api: tuple[InProcess, Store], case: str) -> None:
    small_limits_api, memory_store = refusing_api
    request, status, message = BAD_INPUTS[case]
    before = small_limits_api.get("/events", headers={"Accept": "application/n-triples"}).text

    answer = post(small_limits_api, **request)

    assert answer.status_code == status, answer.text
    body = answer.json()
    assert message in json.dumps(body), body
    assert body["status"] == status
    after = small_limits_api.get("/events", headers={"Accept": "application/n-triples"}).text
    assert after == before
    assert memory_store.count() == 2


def test_malformed_turtle_reports_line_and_column_fields(small_limits_api: InProcess) -> None:
    answer = post(small_limits_api, json={"ttl_content": "@prefix ex: <https://ex.org/> .\nex:a ex:b ex:c ex:d ."})
    assert answer.status_code == 400
    assert answer.json()["line"] == 2
    assert answer.json()["column"] == 16
    assert answer.json()["error"] == "invalid_rdf"


def test_a_later_error_in_a_large_payload_writes_none_of_its_good_triples(
    small_limits_api: InProcess, memory_store: Store
) -> None:
    payload = many_triples(40) + "<https://ex.org/broken> <https://ex.org/p> .\n"
    answer = post(small_limits_api, content=payload.encode(), headers={"Content-Type": "application/n-triples"})
    assert answer.status_code == 400
    assert "line 41" in answer.json()["detail"]
    assert memory_store.count() == 2


def test_raw_turtle_n_triples_and_gzip_are_accepted(small_limits_api: InProcess, memory_store: Store) -> None:
    raw = post(
        small_limits_api,
        content=b'<https://ex.org/t> <https://ex.org/p> "t" .',
        headers={"Content-Type": "text/turtle; charset=utf-8"},
        params={"user": "tester"},
    )
    nt = post(
        small_limits_api,
        content=b'<https://ex.org/n> <https://ex.org/p> "n" .\n',
        headers={"Content-Type": "application/n-triples"},
    )
    zipped = post(
        small_limits_api,
        content=gzip.compress(json.dumps({"ttl_content": many_triples(3)}).encode()),
        headers={"Content-Type": "application/json", "Content-Encoding": "gzip"},
    )

    assert [r.status_code for r in (raw, nt, zipped)] == [201, 201, 201]
    assert raw.json()["claimed_user"] == "tester"
    assert zipped.json()["triples_new"] == 3
    assert memory_store.count() == 2 + 1 + 1 + 3


def test_a_document_with_only_prefixes_is_accepted_with_zero_triples(small_limits_api: InProcess) -> None:
    answer = post(small_limits_api, json={"ttl_content": "@prefix ex: <https://ex.org/> .\n"})
    assert answer.status_code == 201
    assert answer.json()["triples_received"] == 0


def test_blank_nodes_are_skolemised_and_do_not_duplicate_on_republish(
    small_limits_api: InProcess, memory_store: Store
) -> None:
    first = "@prefix ex: <https://ex.org/> .\nex:ari ex:pose [ ex:x 1 ; ex:y 2 ] ; ex:seen [ ex:who ex:maria ] .\n"
    relabelled = (
        "@prefix ex: <https://ex.org/> .\n_:b9 ex:who ex:maria .\nex:ari ex:seen _:b9 .\n"
        "ex:ari ex:pose _:zz .\n_:zz ex:y 2 ; ex:x 1 .\nex:extra ex:p 3 .\n"
    )
    one = post(small_limits_api, json={"ttl_content": first})
    two = post(small_limits_api, json={"ttl_content": relabelled})

    assert one.json()["triples_new"] == 5
    assert two.json()["triples_new"] == 1  # only ex:extra: the same blank nodes got the same IRIs
    exported = small_limits_api.get("/events", headers={"Accept": "application/n-triples"}).text
    assert "_:" not in exported
    assert exported.count("http://amor-segb/.well-known/genid/") == 5  # 3 triples as subject, 2 as object


def test_two_different_cyclic_blank_structures_are_stored_whole_on_each_store(store_server: str) -> None:
    """Posted over HTTP as the client posts, on the embedded store and on Virtuoso: every triple is kept (none
    merged by a shared skolem IRI), and a re-post adds none."""
    first = httpx.post(f"{store_server}/ttl", json={"ttl_content": TWO_CYCLES}, timeout=60)
    again = httpx.post(f"{store_server}/ttl", json={"ttl_content": TWO_CYCLES}, timeout=60)
    assert first.status_code == again.status_code == 201, (first.text, again.text)
    assert (first.json()["triples_received"], first.json()["triples_new"]) == (18, 18)
    assert again.json()["triples_new"] == 0
    exported = httpx.get(f"{store_server}/events", headers={"Accept": "application/n-triples"}, timeout=60).text
    assert len([line for line in exported.splitlines() if line.strip()]) == 18


def test_a_document_that_starts_with_a_byte_order_mark_is_read_without_it(
    small_limits_api: InProcess, memory_store: Store
) -> None:
    # Editors on Windows save UTF-8 with a byte order mark: it is no part of the document (RDF 1.1 Turtle, 6.2).
    bom = "\ufeff"
    raw = post(small_limits_api, content=(bom + GOOD.replace("ari", "tiago")).encode(),
               headers={"Content-Type": "text/turtle"})  # fmt: skip
    assert raw.status_code == 201, raw.text
    wrapped = post(small_limits_api, json={"ttl_content": bom + GOOD.replace("ari", "pepper")})
    assert wrapped.status_code == 201, wrapped.text
    robots = select(memory_store, "SELECT ?robot WHERE { ?robot a <https://ex.org/Robot> }").rows
    assert {row["robot"].value for row in robots} == {f"https://ex.org/{name}" for name in ("ari", "tiago", "pepper")}
