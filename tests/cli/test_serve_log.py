"""What `segb serve` writes to its terminal while robots post odd data: a robot's literal that its datatype does
not admit ("2026-02-30T99:00:00Z"^^xsd:dateTime) is stored as sent and costs no traceback in the log (rdflib
printed one for each such literal the SHACL check read)."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest

from tests.cli.test_cli import SEGB, clean_env
from tests.support.net import free_port
from tests.support.processes import running
from tests.support.settle import settle

BAD_TIMES = """
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
@prefix prov: <http://www.w3.org/ns/prov#> .
<https://example.org/act/1> a prov:Activity ; prov:startedAtTime "notadate"^^xsd:dateTime .
<https://example.org/act/2> a prov:Activity ; prov:startedAtTime "2026-02-30T99:00:00Z"^^xsd:dateTime .
<https://example.org/act/3> a prov:Activity ; prov:startedAtTime "-0044-03-15T00:00:00Z"^^xsd:dateTime .
"""


@pytest.mark.processes
def test_a_literal_its_datatype_does_not_admit_is_stored_without_a_traceback(tmp_path: Path) -> None:
    port, log = free_port(), tmp_path / "serve.log"
    argv = [*SEGB, "serve", "--only", "api", "--data-dir", str(tmp_path / "data"), "--api-port", str(port)]
    url = f"http://127.0.0.1:{port}"
    with running(argv, ready=f"{url}/healthz/ready", env=clean_env(), log=log):
        posted = httpx.post(f"{url}/ttl", content=BAD_TIMES, headers={"content-type": "text/turtle"}, timeout=30)
        assert posted.status_code == 201, posted.text
        settle(url)
        stored = httpx.post(
            f"{url}/sparql", data={"query": "SELECT ?t { ?a <http://www.w3.org/ns/prov#startedAtTime> ?t }"}
        )
        assert "notadate" in stored.text and "2026-02-30T99:00:00Z" in stored.text
    written = log.read_text()
    assert "Traceback" not in written, written[-3000:]
