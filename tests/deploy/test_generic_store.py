"""The generic SPARQL 1.1 adapter (STORE=sparql) on a second real store: Oxigraph's own server (`oxigraph serve`,
the `oxigraph` package on PyPI), run as a process of its own, with two API workers in front of it."""

from __future__ import annotations

import os
import shutil
import sysconfig
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.api.test_reports_differential import REPORTS, bound_text, full_evaluation, report_rows, same_rows
from tests.cli.test_cli import SEGB, clean_env
from tests.deploy.test_workers import post_until_spread
from tests.faults.test_crashes import caught_up, check_consistent
from tests.support.net import free_port
from tests.support.processes import running
from tests.support.scenarios import lobby

pytestmark = pytest.mark.processes  # runs Oxigraph's server and API workers


def oxigraph_binary() -> str | None:
    """The `oxigraph` executable pip installed beside this interpreter's scripts (or for the user), else on PATH."""
    for scheme in (sysconfig.get_default_scheme(), f"{os.name}_user"):
        candidate = Path(sysconfig.get_path("scripts", scheme)) / "oxigraph"
        if candidate.is_file():
            return str(candidate)
    return shutil.which("oxigraph")


@pytest.fixture
def oxigraph_server(tmp_path: Path) -> Iterator[str]:
    binary = oxigraph_binary()
    assert binary, "the oxigraph server is installed from requirements-test.lock"
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    location = tmp_path / "oxigraph-server"
    argv = [binary, "serve", "--location", str(location), "--bind", f"127.0.0.1:{port}"]
    with running(argv, ready=f"{url}/query?query=ASK%7B%7D", timeout=30):
        yield url


@pytest.fixture
def api_on_oxigraph_server(oxigraph_server: str, tmp_path: Path) -> Iterator[str]:
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    env = {
        "STORE": "sparql",
        "SPARQL_QUERY_ENDPOINT": f"{oxigraph_server}/query",
        "SPARQL_UPDATE_ENDPOINT": f"{oxigraph_server}/update",
        "VIEWS_PROCESS": "true",  # off by default on a remote store: asked for, the views run beside the workers
    }
    command = ["serve", "--only", "api", "--workers", "2", "--data-dir", str(tmp_path / "data")]
    argv = [*SEGB, *command, "--api-port", str(port)]
    with running(argv, ready=f"{url}/healthz/live", env=clean_env(env), log=tmp_path / "api.log"):
        yield url


def test_robots_reports_and_graph_work_on_oxigraph_server_behind_two_workers(api_on_oxigraph_server: str) -> None:
    url = api_on_oxigraph_server
    assert httpx.get(f"{url}/healthz/ready", timeout=10).json() == {"ready": True, "sparql": True}
    acknowledged = post_until_spread(url, robot=7)  # both workers take posts
    lobby().publish_all(url)  # the PyPI client
    caught_up(url)
    check_consistent(url, acknowledged)

    # Every report, kept as rows by the leading worker and read by either, equals its query run on the store.
    for query in REPORTS:
        name = query.name.removeprefix("reports/")
        served = report_rows(url, name, {}, page=20)
        same_rows(served, full_evaluation(url, bound_text(query.name, {})), [], name)
        assert httpx.get(f"{url}/reports/{name}", timeout=30).json()["served_from"] == "rows"
    graph = httpx.get(f"{url}/graph", timeout=30)
    assert graph.status_code == 200 and graph.json()["nodes"]
