"""Users' SPARQL on the embedded store runs where it can be stopped: an aggregate over a cross join is ended at
the time limit, with the CPU back to idle and the memory given back, and a query that needs too much memory is
stopped with a 503 saying so, while the server goes on answering."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.cli.test_cli import SEGB, clean_env, wait_for
from tests.support.net import free_port

CROSS_JOIN_COUNT = "SELECT (COUNT(*) AS ?n) WHERE { ?a ?b ?c . ?d ?e ?f . ?g ?h ?i }"
CROSS_JOIN_SORTED = "SELECT ?a ?d ?g WHERE { ?a ?b ?c . ?d ?e ?f . ?g ?h ?i } ORDER BY ?c ?f ?i"
TIMEOUT = 3

pytestmark = pytest.mark.processes  # a server process of its own, to watch its query workers
MEMORY = 300 * 1024 * 1024


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, int]]:
    """`segb serve --only api --demo` as its own process, with a short time limit and a small memory limit."""
    port = free_port()
    data = tmp_path_factory.mktemp("isolation")
    process = subprocess.Popen(
        [*SEGB, "serve", "--only", "api", "--demo", "--data-dir", str(data), "--api-port", str(port)],
        env=clean_env({"SPARQL_TIMEOUT_SECONDS": str(TIMEOUT), "SPARQL_MAX_MEMORY_BYTES": str(MEMORY)}),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}"
    wait_for(f"{url}/healthz/ready", timeout=120)
    yield url, process.pid
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=60) == 0  # SIGTERM stops it, even after the runaway queries


def family(pid: int) -> list[int]:
    """The process and its descendants (the query workers)."""
    found = [pid]
    for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split():
        found += family(int(child))
    return found


def cpu_seconds(pids: list[int]) -> float:
    total = 0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except FileNotFoundError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime + stime, in clock ticks
    return total / os.sysconf("SC_CLK_TCK")


def rss_bytes(pids: list[int]) -> int:
    total = 0
    for pid in pids:
        try:
            status = Path(f"/proc/{pid}/status").read_text()
        except FileNotFoundError:
            continue
        total += next(int(line.split()[1]) * 1024 for line in status.splitlines() if line.startswith("VmRSS:"))
    return total


def test_an_aggregate_over_a_cross_join_is_stopped_at_the_deadline(server: tuple[str, int]) -> None:
    url, pid = server
    started = time.monotonic()
    answer = httpx.get(f"{url}/sparql", params={"query": CROSS_JOIN_COUNT}, timeout=60)
    elapsed = time.monotonic() - started
    assert (answer.status_code, answer.json()["error"]) == (503, "query_timeout")
    assert elapsed < TIMEOUT + 2, f"stopped after {elapsed:.1f} s"
    assert httpx.get(f"{url}/healthz/ready", timeout=5).status_code == 200

    time.sleep(0.5)
    before = cpu_seconds(family(pid))
    time.sleep(2)
    busy = cpu_seconds(family(pid)) - before
    assert busy < 0.5, f"{busy:.2f} CPU seconds in 2 s after the query was stopped"
    assert rss_bytes(family(pid)) < 500 * 1024 * 1024


def test_a_query_past_the_memory_limit_is_stopped_and_says_so(server: tuple[str, int]) -> None:
    url, pid = server
    answer = httpx.get(f"{url}/sparql", params={"query": CROSS_JOIN_SORTED}, timeout=60)
    assert answer.status_code == 503
    assert answer.json()["error"] == "query_memory", answer.text
    assert "SPARQL_MAX_MEMORY_BYTES" in answer.json()["detail"]
    small = httpx.get(f"{url}/sparql", params={"query": "SELECT (COUNT(*) AS ?n) { ?s ?p ?o }"}, timeout=30)
    assert small.status_code == 200 and int(small.json()["results"]["bindings"][0]["n"]["value"]) > 500
    assert rss_bytes(family(pid)) < 500 * 1024 * 1024
