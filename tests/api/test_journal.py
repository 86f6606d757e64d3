"""The journal: each receipt opens the triples it recorded exactly as received, a deep verification re-hashes
them, the graph can be exported as received, the store is rebuilt from it, and one post's failure never
fails another's."""

from __future__ import annotations

import hashlib
import sqlite3
import subprocess
import zlib
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest
from pyoxigraph import RdfFormat

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from tests.cli.test_cli import segb
from tests.conftest import FIXTURES, make_settings
from tests.support.graphs import triples
from tests.support.in_process import InProcess, Server, http, publisher_for
from tests.support.scenarios import lobby

XSD = "http://www.w3.org/2001/XMLSchema#"
AS_SENT = (
    "@prefix ex: <https://e.org/> .\n@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n"
    'ex:reading ex:intensity "8.7e-01"^^xsd:double ; ex:count "5"^^xsd:long ; ex:ok "1"^^xsd:boolean ;\n'
    '  ex:at "2026-03-10T09:00:05.250+00:00"^^xsd:dateTime .\n'
)


def post(server: Server, turtle: str, **headers: str) -> httpx.Response:
    return http(server, "POST", "/ttl", json={"ttl_content": turtle, "user": "ari"}, headers=headers)


@pytest.fixture
def disk_api(tmp_path: Path) -> Iterator[InProcess]:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        yield server


def test_a_receipt_opens_its_new_triples_exactly_as_received(memory_api: InProcess) -> None:
    first = post(memory_api.client, AS_SENT).json()
    entry = memory_api.get(f"/ledger/{first['log_id']}").json()
    kept = entry["content"]
    assert f'"8.7e-01"^^<{XSD}double>' in kept and f'"5"^^<{XSD}long>' in kept and f'"1"^^<{XSD}boolean>' in kept
    assert hashlib.sha256(kept.encode()).hexdigest() == entry["receipt"]["content_sha256"]
    raw = memory_api.get(f"/ledger/{first['log_id']}", headers={"Accept": "application/n-triples"})
    assert raw.content == kept.encode()

    # A cumulative re-publish records only what is new; a pure re-publish records nothing.
    second = post(memory_api.client, AS_SENT + 'ex:reading ex:note "late" .\n').json()
    assert second["triples_new"] == 1
    assert memory_api.get(f"/ledger/{second['log_id']}").json()["content"].count("\n") == 1
    third = post(memory_api.client, AS_SENT).json()
    assert (third["triples_new"], memory_api.get(f"/ledger/{third['log_id']}").json()["content"]) == (0, "")
    assert memory_api.get("/ledger/no-such-id").status_code == 404


def test_the_graph_as_received_keeps_what_the_store_canonicalises(memory_api: InProcess) -> None:
    post(memory_api.client, AS_SENT)
    stored = memory_api.get("/events", params={"format": "ntriples"}).text
    received = memory_api.get("/events", params={"format": "ntriples", "form": "received"}).text
    assert '"0.87"' in stored and '"8.7e-01"' not in stored  # the store's canonical spelling
    assert f'"8.7e-01"^^<{XSD}double>' in received and f'"5"^^<{XSD}long>' in received
    assert triples(received) == triples(AS_SENT, RdfFormat.TURTLE)
    as_turtle = memory_api.get("/events", params={"format": "turtle", "form": "received"}).text
    assert triples(as_turtle, RdfFormat.TURTLE) == triples(received)
    memory_api.post("/ttl/delete_all", json={})
    assert memory_api.get("/events", params={"format": "ntriples", "form": "received"}).text == ""


def test_deep_verification_finds_edited_content(disk_api: InProcess, tmp_path: Path) -> None:
    lobby().publish_all(disk_api.client)
    assert disk_api.get("/ledger/verify", params={"deep": "true"}).json() == {
        "valid": True,
        "receipts": disk_api.get("/ledger").json()["total"],
        "deep": True,
    }
    with sqlite3.connect(tmp_path / "journal.sqlite3") as journal:
        rows = journal.execute("SELECT sequence, content FROM receipts WHERE content != x'' ORDER BY sequence")
        sequence, blob = next((number, blob) for number, blob in rows if b"Maria" in zlib.decompress(blob))
        edited = zlib.decompress(blob).replace(b"Maria", b"Marta")
        journal.execute("UPDATE receipts SET content = ? WHERE sequence = ?", (zlib.compress(edited), sequence))
    shallow = disk_api.get("/ledger/verify").json()
    deep = disk_api.get("/ledger/verify", params={"deep": "true"}).json()
    assert shallow["valid"] is True  # the receipts themselves are intact
    assert (deep["valid"], deep["first_broken"]["sequence"], deep["first_broken"]["reason"]) == (
        False,
        sequence,
        "content does not match",
    )


@pytest.mark.processes
def test_segb_rebuild_makes_the_same_store_again_from_the_journal(tmp_path: Path) -> None:
    loaded = segb("import", "--data-dir", str(tmp_path), str(FIXTURES / "sample_two_robots.ttl"))
    assert loaded.returncode == 0, loaded.stderr
    before = segb("export", "--data-dir", str(tmp_path), "--format", "ntriples").stdout
    rebuilt = segb("rebuild", "--data-dir", str(tmp_path))
    assert rebuilt.returncode == 0, rebuilt.stderr
    assert "rebuilt from the journal" in rebuilt.stdout
    after = segb("export", "--data-dir", str(tmp_path), "--format", "ntriples").stdout
    assert triples(after) == triples(before) and len(triples(before)) == 799


def test_a_hostile_user_in_a_batch_of_honest_robots_fails_alone(disk_api: InProcess) -> None:
    """Posts that share a journal transaction: one robot's bad `user` (a lone surrogate, legal JSON) is refused
    with 422 naming the field; the others all get 201 and their receipts."""
    honest_turtle = '<https://e.org/robot{0}> <https://e.org/says> "hello {1}" .'
    hostile = '{"ttl_content": "<https://e.org/u> <https://e.org/p> \\"x\\" .", "user": "\\ud800"}'

    def honest(robot: int) -> list[int]:
        return [
            disk_api.post("/ttl", json={"ttl_content": honest_turtle.format(robot, n), "user": f"r{robot}"}).status_code
            for n in range(20)
        ]

    def attacker() -> list[httpx.Response]:
        return [disk_api.post("/ttl", content=hostile, headers={"Content-Type": "application/json"}) for _ in range(40)]

    with ThreadPoolExecutor(max_workers=13) as pool:
        honest_runs = [pool.submit(honest, robot) for robot in range(12)]
        hostile_run = pool.submit(attacker)
        statuses = [status for run in honest_runs for status in run.result()]
        refusals = hostile_run.result()
    assert statuses == [201] * 240
    assert {answer.status_code for answer in refusals} == {422}
    assert all("'user'" in answer.json()["detail"] and answer.headers["x-request-id"] for answer in refusals)
    ledger = disk_api.get("/ledger", params={"limit": 1000}).json()
    assert ledger["total"] == 240 and {r["claimed_user"] for r in ledger["receipts"]} == {f"r{n}" for n in range(12)}


@pytest.mark.processes
def test_scoped_tokens_write_only_about_their_namespaces_with_the_pypi_client(tmp_path: Path) -> None:
    secret = "s" * 40
    tiago = mint_token(
        secret,
        username="tiago",
        roles=["logger"],
        scopes=["https://example.org/segb/robots/tiago/", "https://example.org/segb/people/"],
    ).token
    with InProcess(create_app(make_settings(secret_key=secret))) as server:
        own = publisher_for(server.client, token=tiago).publish_turtle(
            '<https://example.org/segb/robots/tiago/v1/robot_tiago> <http://schema.org/name> "TIAGo" .\n'
            '<https://example.org/segb/people/maria> <http://xmlns.com/foaf/0.1/firstName> "Maria" .\n'
            "<https://example.org/segb/robots/tiago/v1/a1> <https://e.org/about> [ <https://e.org/p> 1 ] ."
        )
        assert own["triples_new"] == 4  # its own namespace, the shared one, and its blank nodes
        forged = server.post(
            "/ttl",
            json={
                "ttl_content": "<https://example.org/segb/robots/tiago/v1/x> <https://e.org/p> 1 .\n"
                '<https://example.org/segb/robots/ari/v1/robot_ari> <http://schema.org/name> "evil" .'
            },
            headers={"Authorization": f"Bearer {tiago}"},
        )
        assert forged.status_code == 403
        assert "<https://example.org/segb/robots/ari/v1/robot_ari>" in forged.json()["detail"]
        with pytest.raises(RuntimeError, match="403"):
            publisher_for(server.client, token=tiago).publish_turtle(
                '<https://example.org/segb/robots/ari/v1/robot_ari> <http://schema.org/name> "evil" .'
            )
        # Its own subjects crediting another robot with an act, words or a state: refused too, whoever's subject.
        credits = ("http://www.gsi.upm.es/ontologies/segb/ns#wasPerformedBy", "http://www.w3.org/ns/prov#wasAttributedTo",
                   "http://www.w3.org/ns/prov#wasAssociatedWith", "http://schema.org/sender")  # fmt: skip
        for credit in credits:
            impersonating = server.post(
                "/ttl",
                json={
                    "ttl_content": f"<https://example.org/segb/robots/tiago/v1/reply> <{credit}> "
                    "<https://example.org/segb/robots/ari/v1/robot_ari> ."
                },
                headers={"Authorization": f"Bearer {tiago}"},
            )
            assert impersonating.status_code == 403, (credit, impersonating.text)
            assert "credits <https://example.org/segb/robots/ari/v1/robot_ari>" in impersonating.json()["detail"]
        # What it heard from a person of the shared namespace is its to log.
        heard = publisher_for(server.client, token=tiago).publish_turtle(
            "<https://example.org/segb/robots/tiago/v1/m1> <http://schema.org/sender> "
            "<https://example.org/segb/people/maria> ."
        )
        assert heard["triples_new"] == 1
        whoami = server.get("/auth/whoami", headers={"Authorization": f"Bearer {tiago}"}).json()
        assert whoami["scopes"] == ["https://example.org/segb/robots/tiago/", "https://example.org/segb/people/"]
        ledger = server.get("/ledger", headers={"Authorization": f"Bearer {tiago}"})
        assert ledger.status_code == 403  # a logger token does not read
    minted = subprocess.run(
        [*segb_command(), "token", "--username", "ari", "--role", "logger", "--scope", "https://e.org/ari/", "--json"],
        capture_output=True,
        text=True,
        env={"SECRET_KEY": secret, "PATH": "/usr/bin:/bin"},
        timeout=60,
    )
    assert minted.returncode == 0, minted.stderr
    assert '"scopes": ["https://e.org/ari/"]' in minted.stdout


def segb_command() -> list[str]:
    from tests.cli.test_cli import SEGB

    return SEGB
