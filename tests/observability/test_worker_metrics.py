"""Several API workers' counts summed in one scrape: each process records into PROMETHEUS_MULTIPROC_DIR (the
folder `segb serve --workers N` makes and removes), and whichever answers the scrape reads them all."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from segb_server.backend.services.observability.worker_metrics import VARIABLE, metrics_shared_by_workers
from tests.observability.exposition import samples, value

pytestmark = pytest.mark.processes

WORKER = """
from segb_server.backend.services.observability.metrics import record_post
for _ in range({posts}):
    record_post(201, None, 0.01, {{"new": 2}})
record_post(400, "invalid_rdf", 0.002, {{}})
"""
SCRAPE = """
import sys
from segb_server.backend.services.observability.metrics import exposition, multiprocess
assert multiprocess()
sys.stdout.write(exposition([]).decode())
"""


def run(code: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", code], env=dict(os.environ), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_a_scrape_sums_what_every_worker_counted_and_the_folder_goes_afterwards() -> None:
    with metrics_shared_by_workers() as folder:
        assert os.environ[VARIABLE] == folder
        run(WORKER.format(posts=2))
        run(WORKER.format(posts=3))
        found = samples(run(SCRAPE))
    assert VARIABLE not in os.environ and not Path(folder).exists()
    assert value(found, "segb_posts_total", outcome="accepted", reason="") == 5
    assert value(found, "segb_posts_total", outcome="refused", reason="invalid_rdf") == 2
    assert value(found, "segb_triples_total", outcome="new") == 10
    assert value(found, "segb_ingest_seconds_count", outcome="accepted") == 5
