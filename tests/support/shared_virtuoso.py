"""The Virtuoso the tests share (the `virtuoso` fixture of tests/conftest.py), watched: should it stop while a test
uses it, the test is run once more on a Virtuoso started again, and the run's summary says so with Virtuoso's log.

Why: a Virtuoso that stops takes with it every test after it that reads the store (a CI run once failed 182 tests
so, the store gone from one test to the end). The test during which it stopped is run again, not let pass: it
passes only if it passes whole on the restarted store, and a test that stops Virtuoso every time it runs fails.
Registered by tests/conftest.py."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import pytest
from _pytest.runner import runtestprotocol

from tests.support.virtuoso import VirtuosoProcess

# Past this many stops in one run the store is not failing by chance: the tests fail as they are.
MOST_RESTARTS = 3


@dataclass(frozen=True)
class Stop:
    """Virtuoso stopped while `test` ran: the code it exited with, the end of its log, how the test ended."""

    test: str
    exit_code: int
    log: str
    outcome: str


_STOPPED = pytest.StashKey[Stop]()
_stops: list[Stop] = []


@pytest.fixture(autouse=True)
def _shared_virtuoso_outlives_the_test(request: pytest.FixtureRequest) -> Iterator[None]:
    """After each test using the shared Virtuoso: if it stopped, say so (the test errors in its teardown) and start
    it again on the same database, so the tests after it test the server rather than a store that is gone."""
    yield
    if "virtuoso" not in request.fixturenames:
        return
    process: VirtuosoProcess = request.getfixturevalue("virtuoso")
    code = process.exit_code()
    if code is None:
        return
    log = process.log_tail()
    process.start()
    request.node.stash[_STOPPED] = Stop(request.node.nodeid, code, log, outcome="")
    pytest.fail(f"the shared Virtuoso stopped during this test (exit code {code}); the end of its log:\n{log}")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> bool | None:
    """Run a test that can use the shared Virtuoso; once more if Virtuoso stopped during it (setup passed)."""
    if "virtuoso" not in item.keywords and "virtuoso" not in getattr(item, "fixturenames", ()):
        return None  # pytest's own protocol
    item.ihook.pytest_runtest_logstart(nodeid=item.nodeid, location=item.location)
    reports = runtestprotocol(item, nextitem=nextitem, log=False)
    stop = item.stash.get(_STOPPED, None)
    if stop is not None and reports[0].passed and len(_stops) < MOST_RESTARTS:
        del item.stash[_STOPPED]
        failed = [f"{report.when}: {report.longreprtext}" for report in reports if report.failed]
        _stops.append(replace(stop, outcome="\n".join(failed)))
        reports = runtestprotocol(item, nextitem=nextitem, log=False)
    for report in reports:
        item.ihook.pytest_runtest_logreport(report=report)
    item.ihook.pytest_runtest_logfinish(nodeid=item.nodeid, location=item.location)
    return True


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    for stop in _stops:
        terminalreporter.write_sep("=", "the shared Virtuoso stopped; the test was run again", yellow=True)
        terminalreporter.write_line(f"{stop.test}: Virtuoso exited with code {stop.exit_code}")
        terminalreporter.write_line(f"the first run: {stop.outcome}")
        terminalreporter.write_line(f"the end of Virtuoso's log:\n{stop.log}")
