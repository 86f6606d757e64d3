"""An erasure killed with SIGKILL: after the restart it is either fully done (its entry in the ledger, the person
gone from the store, the journal's posts and the reports) or not started (no entry, everything of hers still
there, to be erased again), and the journal verifies deep either way."""

from __future__ import annotations

import contextlib
import random
import threading
import time
from pathlib import Path

import httpx
import pytest

from tests.faults.test_crashes import Server, caught_up
from tests.support.people import INES_SAYS, care_home, filler
from tests.support.settle import settle

pytestmark = pytest.mark.processes  # kills servers it started

FILLER = 150_000  # triples of other posts: the embedded store takes a moment to be written anew without her


def erase_quietly(url: str, iri: str) -> None:
    with contextlib.suppress(httpx.HTTPError):
        httpx.post(f"{url}/humans/erase", json={"iri": iri, "reason": "crash test"}, timeout=300)


def state_of(url: str, iri: str) -> str:
    """`done` or `not started`, after checking that the store, the posts and the reports all say the same."""
    erasures = [
        r for r in httpx.get(f"{url}/ledger", params={"limit": 1000}).json()["receipts"] if r["action"] == "erase"
    ]
    stored = httpx.get(f"{url}/events", params={"format": "ntriples"}, timeout=120).text
    received = httpx.get(f"{url}/events", params={"format": "ntriples", "form": "received"}, timeout=120).text
    rows = httpx.get(f"{url}/reports/participants", params={"human": iri}).json()["rows"]
    held = [INES_SAYS[0] in stored, INES_SAYS[0] in received, iri in stored, iri in received, bool(rows)]
    verified = httpx.get(f"{url}/ledger/verify", params={"deep": "true"}, timeout=120).json()
    assert verified["valid"] is True, verified
    if erasures:
        assert held == [False] * 5 and verified["redactions"] == len(erasures), held
        return "done"
    assert held == [True] * 5, held
    return "not started"


def erasure_recorded(url: str) -> bool:
    receipts = httpx.get(f"{url}/ledger", params={"limit": 1}, timeout=10).json()["receipts"]
    return bool(receipts) and receipts[0]["action"] == "erase"


def test_sigkill_during_an_erasure_leaves_it_done_or_not_started(tmp_path: Path) -> None:
    server = Server(tmp_path / "data")
    server.start()
    try:
        visit = care_home()
        visit.publish_steps(server.url)
        others = filler(FILLER // 2)
        headers = {"Content-Type": "application/n-triples"}
        assert httpx.post(f"{server.url}/ttl", content=others, headers=headers, timeout=300).status_code == 201
        ines = str(visit.iris["ines"])

        # Killed while it looks for what to erase: not started, and the ledger has no erasure. (On a fast machine
        # it may have been recorded already when the kill comes; then the restart must finish it.)
        eraser = threading.Thread(target=erase_quietly, args=(server.url, ines), daemon=True)
        eraser.start()
        time.sleep(random.uniform(0.01, 0.03))
        recorded = erasure_recorded(server.url)
        server.kill()
        eraser.join(timeout=60)
        server.start()
        caught_up(server.url)
        settle(server.url, timeout=300)
        assert state_of(server.url, ines) == ("done" if recorded else "not started")
        if recorded:
            return

        # Killed once its entry is in the journal, while the store is being written anew without her: after the
        # restart the applier applies the entry again, and it is done.
        # The kill follows the rewrite's folder appearing on disk (the applier starts it once the entry is
        # journaled), not a look at the ledger over HTTP: a rewrite can end before such an answer comes back.
        rewriting = tmp_path / "data" / "oxigraph.rewriting"
        eraser = threading.Thread(target=erase_quietly, args=(server.url, ines), daemon=True)
        eraser.start()
        deadline = time.monotonic() + 60
        while not rewriting.exists():
            assert time.monotonic() < deadline, "the store was never written anew"
            time.sleep(0.001)
        server.kill()
        assert rewriting.exists()  # the kill came in the middle of the rewrite
        eraser.join(timeout=60)
        server.start()
        caught_up(server.url)
        settle(server.url, timeout=300)
        assert state_of(server.url, ines) == "done"
        assert not (tmp_path / "data" / "oxigraph.rewriting").exists()
    finally:
        server.stop()
