"""Shared fixtures: settings isolated from the environment, real stores, a real Virtuoso, the API served in
process, live servers."""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings as hypothesis_settings
from hypothesis.configuration import set_hypothesis_home_dir

from segb_server.backend.api.app import create_app
from segb_server.backend.config import Settings
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.store.virtuoso import VirtuosoStore
from tests.support.browser import CHROMIUM, CHROMIUM_ARGS
from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer
from tests.support.postgres import PostgresProcess
from tests.support.virtuoso import VirtuosoProcess
from tests.support.write_guard import differences, redirect_home, take

ROOT = Path(__file__).resolve().parents[1]

FIXTURES = Path(__file__).resolve().parent / "fixtures"  # Turtle from the real robot client (see its README)
STORE_KINDS = ["oxigraph", pytest.param("virtuoso", marks=pytest.mark.virtuoso)]

# A test during which the shared Virtuoso stops is run once more on a Virtuoso started again (see the module).
pytest_plugins = ("tests.support.shared_virtuoso",)


# Property tests keep no example database, and hypothesis's own files go to a temporary directory: the suite
# writes nothing outside temporary directories.
hypothesis_settings.register_profile("segb", database=None, deadline=None)
hypothesis_settings.load_profile("segb")
_HYPOTHESIS_HOME = Path(tempfile.mkdtemp(prefix="segb-test-hypothesis-"))
set_hypothesis_home_dir(str(_HYPOTHESIS_HOME))


# The fast tier (`pytest --fast`, `./scripts/test.sh --fast`): every test but those needing a real part or a
# process of their own, and the few that run for many seconds by design. The full suite runs them all.
NOT_FAST = frozenset({"virtuoso", "browser", "postgres", "containers", "processes", "slow"})


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--fast",
        action="store_true",
        help=f"the fast tier: deselect the tests marked {', '.join(sorted(NOT_FAST))}",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # The container tier runs after everything else: it takes minutes, and the rest reports first.
    items.sort(key=lambda item: item.get_closest_marker("containers") is not None)  # stable: order kept within
    if not config.getoption("--fast"):
        return
    kept, deselected = [], []
    for item in items:
        (deselected if NOT_FAST & {marker.name for marker in item.iter_markers()} else kept).append(item)
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = kept


def pytest_configure(config: pytest.Config) -> None:
    real_home = redirect_home()
    config.stash[_GUARD] = (real_home, take(ROOT, real_home))
    sys.addaudithook(_refuse_unmarked_processes)


# A test that starts a process (the segb command, a store, a browser, a tool) carries a marker saying so, so
# the fast tier (`scripts/test.sh --fast`), which deselects these markers, runs no process but the server's own
# query workers (multiprocessing, which Python does not audit as a subprocess).
PROCESS_MARKERS = frozenset({"processes", "virtuoso", "postgres", "browser", "containers"})
_RUNNING: list[pytest.Item] = []


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item) -> Iterator[None]:
    _RUNNING.append(item)
    try:
        return (yield)
    finally:
        _RUNNING.pop()


def _refuse_unmarked_processes(event: str, arguments: tuple[object, ...]) -> None:
    if event != "subprocess.Popen" or not _RUNNING:
        return
    item = _RUNNING[-1]
    if not PROCESS_MARKERS & {marker.name for marker in item.iter_markers()}:
        raise RuntimeError(
            f"{item.nodeid} starts a process ({arguments[0]!r}): mark it with one of {sorted(PROCESS_MARKERS)}"
        )


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if os.environ.get("SEGB_WRITE_GUARD") == "0":  # while other work edits the tree during a run (never in CI)
        return
    real_home, before = session.config.stash[_GUARD]
    problems = differences(before, take(ROOT, real_home))
    if problems:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        lines = "\n".join(f"  {problem}" for problem in problems)
        message = f"the test run wrote outside temporary directories:\n{lines}"
        if reporter is not None:
            reporter.write_line(message, red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if ARTIFACTS.is_dir() and any(ARTIFACTS.iterdir()):
        terminalreporter.write_line(f"browser screenshots: {ARTIFACTS}")


_GUARD = pytest.StashKey[tuple[Path, object]]()
_DATA_ROOT = Path(tempfile.mkdtemp(prefix="segb-test-data-"))


def make_settings(**overrides: object) -> Settings:
    """Settings that ignore the developer's environment and `.env`, with a data directory of their own."""
    # ingest_ack "store": a test's post is in the store when it is answered, whatever the store (tests of the
    # journal's acknowledgement set it themselves).
    values: dict[str, object] = {"secret_key": "", "store": "memory", "cors_origins": "", "ingest_ack": "store"}
    values.update(overrides)
    values.setdefault("data_dir", Path(tempfile.mkdtemp(dir=_DATA_ROOT)))
    return Settings(_env_file=None, **values)  # type: ignore[call-arg]


@pytest.fixture(scope="session")
def virtuoso(tmp_path_factory: pytest.TempPathFactory) -> Iterator[VirtuosoProcess]:
    process = VirtuosoProcess(tmp_path_factory.mktemp("virtuoso"))
    process.start()
    yield process
    process.stop()


@pytest.fixture(scope="session")
def postgres() -> Iterator[PostgresProcess]:
    process = PostgresProcess()
    process.start()
    yield process
    process.remove()


@pytest.fixture
def postgres_url(postgres: PostgresProcess) -> str:
    """A new, empty database on the shared PostgreSQL server."""
    return postgres.create_database(f"segb_{uuid.uuid4().hex[:16]}")


def virtuoso_store(process: VirtuosoProcess, graph_uri: str | None = None) -> VirtuosoStore:
    """A store on the shared Virtuoso, in a graph of its own so tests never see each other's data."""
    return VirtuosoStore(
        endpoint=process.endpoint,
        user=process.user,
        password=process.password,
        graph_uri=graph_uri or f"http://amor-segb/test/{uuid.uuid4().hex}",
    )


@pytest.fixture(params=STORE_KINDS)
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Store]:
    """Each test using it runs on the embedded store (on disk) and on a real Virtuoso."""
    if request.param == "virtuoso":
        opened: Store = virtuoso_store(request.getfixturevalue("virtuoso"))
    else:
        opened = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    yield opened
    if request.param == "virtuoso":
        opened.clear()
    opened.close()


@pytest.fixture
def store_server(store: Store, tmp_path: Path) -> Iterator[str]:
    """The API over real HTTP on each store, with a data directory of its own (its views on disk): its URL."""
    with LiveServer(create_app(make_settings(store=store.kind, data_dir=tmp_path / "data"), store=store)) as live:
        yield live.url


@pytest.fixture
def memory_store() -> Iterator[Store]:
    opened = OxigraphStore("http://amor-segb/events")
    yield opened
    opened.close()


@pytest.fixture
def api(store: Store) -> Iterator[InProcess]:
    """The API served in this process (no socket), on each store."""
    with InProcess(create_app(make_settings(), store=store)) as served:
        yield served


@pytest.fixture
def memory_api(memory_store: Store) -> Iterator[InProcess]:
    """The API served in this process on a fresh in-memory store (for tests where the store kind is irrelevant)."""
    with InProcess(create_app(make_settings(), store=memory_store)) as served:
        yield served


@pytest.fixture
def live_api(memory_store: Store) -> Iterator[LiveServer]:
    """The API over real HTTP on a fresh in-memory store, for clients that need a socket (other HTTP libraries,
    streams read with a timeout)."""
    with LiveServer(create_app(make_settings(), store=memory_store)) as server:
        yield server


# --- the web UI and a real browser --------------------------------------------------------------------

# Screenshots of every browser test's final state, kept as evidence outside the working tree
# (SEGB_TEST_ARTIFACTS chooses where; by default a temporary directory that the run prints).
ARTIFACTS = Path(os.environ.get("SEGB_TEST_ARTIFACTS") or tempfile.mkdtemp(prefix="segb-test-artifacts-"))


def _remove_temporary() -> None:
    """What this process made in the temporary directory goes when it ends (each xdist worker its own); the
    browser screenshots stay when there are any, where the run printed."""
    for path in (_DATA_ROOT, _HYPOTHESIS_HOME):
        shutil.rmtree(path, ignore_errors=True)
    if "SEGB_TEST_ARTIFACTS" not in os.environ and ARTIFACTS.is_dir() and not any(ARTIFACTS.iterdir()):
        ARTIFACTS.rmdir()


atexit.register(_remove_temporary)


class UiStack:
    """The API and the UI, each on its own live HTTP server, the UI talking to the API over HTTP."""

    def __init__(self, api: LiveServer, ui: LiveServer, store: Store) -> None:
        self.api_url = api.url
        self.ui_url = ui.url
        self.store = store


def start_ui_stack(store: Store, **settings: object) -> Iterator[UiStack]:
    from segb_server.ui.app import create_ui_app

    with LiveServer(create_app(make_settings(**settings), store=store)) as api:
        ui_settings = make_settings(backend_url=api.url, **settings)
        with LiveServer(create_ui_app(ui_settings)) as ui:
            yield UiStack(api, ui, store)


@pytest.fixture
def ui_stack(memory_store: Store) -> Iterator[UiStack]:
    yield from start_ui_stack(memory_store)


@pytest.fixture(scope="session")
def browser() -> Iterator[object]:
    import shutil

    from playwright.sync_api import sync_playwright

    if shutil.which("chromium") is None and not Path(CHROMIUM).exists():
        raise RuntimeError("chromium not found: install Debian's chromium (.ci/run does)")
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def page(browser: object, request: pytest.FixtureRequest) -> Iterator[object]:
    """A fresh page. `page.console_errors` collects console errors and uncaught exceptions; a screenshot
    of the final state is saved under test-artifacts/ as evidence."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})  # type: ignore[attr-defined]
    opened = context.new_page()
    errors: list[str] = []
    opened.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    opened.on("pageerror", lambda error: errors.append(str(error)))
    opened.console_errors = errors
    yield opened
    ARTIFACTS.mkdir(exist_ok=True)
    name = request.node.name.replace("/", "_").replace("[", "-").replace("]", "")
    try:
        opened.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=True)
    finally:
        context.close()
