"""A cumulative re-publish through HTTP, as the PyPI client sends it (its robot's whole graph, serialised by
rdflib, every time): blocks the robot's account sent and had recorded are skipped unparsed, and nothing else
changes — a changed literal is stored, an erased person stays withheld, a syntax error is refused at its line
and column, two robots sharing blocks each get their receipts, and the store is what one post of the same
content makes, on both stores."""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator

import httpx
import pytest
from pyoxigraph import RdfFormat

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from segb_server.backend.store.base import Store
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission
from tests.conftest import make_settings
from tests.support.graphs import value_triples
from tests.support.in_process import InProcess
from tests.support.robot_posts import mission, run_exchange

SECRET = "republish-blocks-test-secret-0123456789abcdef"
VISITOR = "https://example.org/segb/robots/mirror/v1/human_mirror_visitor"
PARSED = re.compile(r"received=(\d+) parsed=(\d+)")
# A block with blank nodes, nested and labelled, shared with the next block by its label.
BLANK_BLOCKS = (
    '\n\nmirror:notes mirror:says [ mirror:text "nested" ; mirror:inner [ mirror:text "deeper" ] ] ;\n'
    "    mirror:points _:shared .\n\n"
    '_:shared mirror:text "shared label" .\n'
)


@pytest.fixture
def served() -> Iterator[InProcess]:
    with InProcess(create_app(make_settings())) as api:
        yield api


def robot_after(exchanges: int, name: str = "mirror") -> EmotionMirrorMission:
    robot = mission(name)
    for index in range(exchanges):
        run_exchange(robot, index)
    return robot


def publish(api: InProcess, ttl: str, **options: object) -> httpx.Response:
    return api.post("/ttl", json={"ttl_content": ttl, "user": "mirror"}, **options)  # type: ignore[arg-type]


def stored(api: InProcess) -> set[tuple[str, str, object]]:
    return value_triples(stored_text(api), RdfFormat.N_TRIPLES)


def stored_text(api: InProcess) -> str:
    answer = api.get("/events", headers={"Accept": "application/n-triples"})
    assert answer.status_code == 200
    return answer.text


def parsed_of_last_post(caplog: pytest.LogCaptureFixture) -> tuple[int, int]:
    lines = [PARSED.search(record.getMessage()) for record in caplog.records if record.name == "segb.ingest"]
    found = [line for line in lines if line]
    assert found, "no ingest line was logged"
    return int(found[-1].group(1)), int(found[-1].group(2))


def test_a_republish_parses_only_the_new_interaction(served: InProcess, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG, logger="segb.ingest")
    robot = robot_after(20)
    assert publish(served, robot.logger.serialize()).status_code == 201
    run_exchange(robot, 20)

    answer = publish(served, robot.logger.serialize()).json()

    received, parsed = parsed_of_last_post(caplog)
    assert answer["triples_received"] == received == len(robot.logger.graph)
    assert answer["triples_new"] > 0
    assert parsed < received / 10  # the twenty earlier interactions were skipped
    assert stored(served) == value_triples(robot.logger.serialize().encode(), RdfFormat.TURTLE)


def test_one_changed_literal_deep_inside_an_unchanged_looking_document_is_stored(
    served: InProcess, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="segb.ingest")
    ttl = robot_after(30).logger.serialize()
    publish(served, ttl)
    publish(served, ttl)
    assert "Utterance 13: I passed" in ttl
    changed = ttl.replace("Utterance 13: I passed", "Utterance 13: I failed")

    answer = publish(served, changed).json()

    assert answer["triples_new"] >= 1
    assert parsed_of_last_post(caplog)[1] < answer["triples_received"] / 10
    assert "Utterance 13: I failed" in stored_text(served)


def test_a_resent_block_after_an_erasure_stays_withheld(served: InProcess) -> None:
    ttl = robot_after(10).logger.serialize()
    publish(served, ttl)
    publish(served, ttl)  # every block now remembered as recorded

    erased = served.post("/humans/erase", json={"iri": VISITOR, "reason": "request"})
    assert erased.status_code == 200, erased.text
    first = publish(served, ttl).json()
    again = publish(served, ttl).json()

    assert first["triples_withheld"] > 0
    assert again["triples_withheld"] == first["triples_withheld"]
    assert first["triples_new"] == again["triples_new"] == 0
    assert first["triples_received"] == again["triples_received"]
    assert VISITOR not in stored_text(served)


def test_a_syntax_error_late_in_a_mostly_resent_document_is_refused_with_its_line_and_column(
    served: InProcess,
) -> None:
    ttl = robot_after(10).logger.serialize()
    publish(served, ttl)
    publish(served, ttl)
    last = ttl.rstrip().rsplit("\n\n", 1)[1]
    broken = ttl.replace(last, last.replace(" ;\n", " ;;\n    ) ;\n", 1))
    with InProcess(create_app(make_settings())) as fresh:
        expected = publish(fresh, broken)

    refused = publish(served, broken)

    assert expected.status_code == refused.status_code == 400
    assert (refused.json()["line"], refused.json()["column"]) == (expected.json()["line"], expected.json()["column"])
    assert refused.json()["line"] > ttl.count("\n") - last.count("\n") - 2


def test_the_same_blocks_under_another_prefix_are_other_triples(served: InProcess) -> None:
    ttl = robot_after(5).logger.serialize()
    publish(served, ttl)
    publish(served, ttl)
    elsewhere = ttl.replace("<https://example.org/segb/robots/mirror/v1/>", "<https://example.org/elsewhere/>", 1)

    answer = publish(served, elsewhere).json()

    moved = {triple for triple in stored(served) if "example.org/elsewhere/" in str(triple)}
    assert answer["triples_new"] == len(moved) > 0


def test_a_blank_line_inside_a_long_literal_is_read_whole(served: InProcess) -> None:
    ttl = robot_after(3).logger.serialize()
    poem = '\n\nmirror:poem mirror:text """first verse .\n\nmirror:fake mirror:p "x" .\n\nlast verse""" .\n'
    publish(served, ttl + poem)
    publish(served, ttl + poem)

    answer = publish(served, ttl + poem.replace("last verse", "last verse, changed")).json()

    assert answer["triples_new"] == 1
    text = stored_text(served)
    assert r'"first verse .\n\nmirror:fake mirror:p \"x\" .\n\nlast verse, changed"' in text
    assert "mirror/v1/fake" not in text


def test_a_clearing_between_posts_stores_everything_again(served: InProcess) -> None:
    ttl = robot_after(5).logger.serialize()
    publish(served, ttl)
    publish(served, ttl)
    assert served.post("/ttl/delete_all", json={}).status_code == 200

    answer = publish(served, ttl).json()

    assert answer["triples_new"] == answer["triples_received"]
    assert stored(served) == value_triples(ttl.encode(), RdfFormat.TURTLE)


def test_two_robots_sharing_byte_identical_blocks_each_get_their_receipts() -> None:
    settings = make_settings(secret_key=SECRET)
    tokens = {name: mint_token(SECRET, username=name, roles=["logger"]).token for name in ("ari", "bo")}
    auditor = {"Authorization": f"Bearer {mint_token(SECRET, username='au', roles=['auditor']).token}"}
    shared = robot_after(6).logger.serialize()
    own = {
        name: f'\n\n<https://example.org/{name}> <https://example.org/says> "{name} was here" .\n' for name in tokens
    }
    with InProcess(create_app(settings)) as api:
        answers: dict[str, list[dict]] = {name: [] for name in tokens}
        for _ in range(3):
            for name, token in tokens.items():
                answer = publish(api, shared + own[name], headers={"Authorization": f"Bearer {token}"})
                assert answer.status_code == 201, answer.text
                answers[name].append(answer.json())
        ledger = api.get("/ledger", params={"limit": 10}, headers=auditor).json()
        verified = api.get("/ledger/verify", params={"deep": "true"}, headers=auditor).json()

    total = len(value_triples((shared + own["ari"]).encode(), RdfFormat.TURTLE))
    for name in tokens:
        assert [answer["triples_received"] for answer in answers[name]] == [total] * 3
        assert [answer["user"] for answer in answers[name]] == [name] * 3
    assert answers["ari"][0]["triples_new"] == total
    assert answers["bo"][0]["triples_new"] == 1  # the shared blocks were ari's already
    receipts = [entry for entry in ledger["receipts"] if entry["action"] == "ingest"]
    assert sorted(entry["user"] for entry in receipts) == ["ari"] * 3 + ["bo"] * 3
    assert all(entry["triples_received"] == total for entry in receipts)
    assert verified["valid"] is True


def test_the_store_after_cumulative_posts_equals_the_same_content_posted_once(store: Store) -> None:
    robot = robot_after(4)
    documents = []
    for index in range(4, 12):
        run_exchange(robot, index)
        documents.append(robot.logger.serialize() + BLANK_BLOCKS)
    documents.append(documents[-1])
    with InProcess(create_app(make_settings(store=store.kind), store=store)) as api:
        answers = [publish(api, ttl).json() for ttl in documents]
        cumulative = stored(api)
        assert api.post("/ttl/delete_all", json={}).status_code == 200
        once = publish(api, documents[-1]).json()
        assert stored(api) == cumulative

    assert once["triples_received"] == answers[-1]["triples_received"]
    assert answers[-1]["triples_new"] == 0
    assert sum(answer["triples_new"] for answer in answers) == once["triples_new"] == len(cumulative)
    blank_free = {triple for triple in cumulative if "/.well-known/genid/" not in str(triple)}
    assert blank_free == value_triples(robot.logger.serialize().encode(), RdfFormat.TURTLE)
