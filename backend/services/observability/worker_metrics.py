"""The folder where API workers record their metrics, so that a scrape answered by any one of them sums them all."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager

# prometheus-client's own variable: a process that has it when the library is imported records into files there.
VARIABLE = "PROMETHEUS_MULTIPROC_DIR"


@contextmanager
def metrics_shared_by_workers() -> Iterator[str]:
    """A fresh folder in the environment the workers inherit, for as long as they run, removed afterwards (a
    folder left from an earlier run would add its counts to this one's)."""
    folder = tempfile.mkdtemp(prefix="segb-metrics-")
    before = os.environ.get(VARIABLE)
    os.environ[VARIABLE] = folder
    try:
        yield folder
    finally:
        if before is None:
            os.environ.pop(VARIABLE, None)
        else:
            os.environ[VARIABLE] = before
        shutil.rmtree(folder, ignore_errors=True)
