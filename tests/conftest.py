"""Shared fixtures: settings isolated from the environment, real stores, a real Virtuoso, live servers."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from backend.api.app import create_app
from backend.config import Settings
from backend.store.base import Store
from backend.store.oxigraph import OxigraphStore
from backend.store.virtuoso import VirtuosoStore
from tests.support.live_server import LiveServer
from tests.support.virtuoso import VirtuosoProcess

SHARED = Path(__file__).resolve().parents[2] / "shared"
FIXTURES = SHARED / "fixtures"
STORE_KINDS = ["oxigraph", pytest.param("virtuoso", marks=pytest.mark.virtuoso)]


def make_settings(**overrides: object) -> Settings:
    """Settings that ignore the developer's environment and `.env`."""
    values: dict[str, object] = {"secret_key": "", "store": "memory", "cors_origins": ""}
    values.update(overrides)
    return Settings(_env_file=None, **values)  # type: ignore[call-arg]


@pytest.fixture(scope="session")
def virtuoso(tmp_path_factory: pytest.TempPathFactory) -> Iterator[VirtuosoProcess]:
    process = VirtuosoProcess(tmp_path_factory.mktemp("virtuoso"))
    process.start()
    yield process
    process.stop()


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
def memory_store() -> Iterator[Store]:
    opened = OxigraphStore("http://amor-segb/events")
    yield opened
    opened.close()


@pytest.fixture
def api(store: Store) -> Iterator[LiveServer]:
    """The API over real HTTP, on each store."""
    with LiveServer(create_app(make_settings(), store=store)) as server:
        yield server


@pytest.fixture
def memory_api(memory_store: Store) -> Iterator[LiveServer]:
    """The API over real HTTP on a fresh in-memory store (for tests where the store kind is irrelevant)."""
    with LiveServer(create_app(make_settings(), store=memory_store)) as server:
        yield server
