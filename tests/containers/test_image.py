"""The project's image, built from its unchanged Dockerfile by both of Docker's builders, and run."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.containers.conftest import timed
from tests.containers.stack import Checkout
from tests.support.docker import DockerDaemon
from tests.support.standins import standin

pytestmark = pytest.mark.containers

CLASSIC = "segb-test/server:classic"
BUILDKIT = "segb-test/server:buildkit"


@pytest.fixture(scope="module")
def checkout(docker_daemon: DockerDaemon, standins: None, tmp_path_factory: pytest.TempPathFactory) -> Checkout:
    return Checkout(docker_daemon, tmp_path_factory.mktemp("image"))


def build(checkout: Checkout, tag: str, *, buildkit: bool) -> str:
    """`docker build` of the checkout with the stand-in base as PYTHON_IMAGE; its output."""
    built = checkout.daemon.docker(
        "build",
        "--no-cache",
        "--build-arg",
        f"PYTHON_IMAGE={standin('python')}",
        "-t",
        tag,
        ".",
        cwd=checkout.directory,
        env={"DOCKER_BUILDKIT": "1" if buildkit else "0"},
        check=False,
    )
    assert built.returncode == 0, built.stdout[-4000:] + built.stderr[-4000:]
    return built.stdout + built.stderr


@pytest.fixture(scope="module")
def classic_image(checkout: Checkout) -> str:
    with timed("image build (classic)"):
        build(checkout, CLASSIC, buildkit=False)
    return CLASSIC


def test_buildkit_builds_the_image_with_no_registry_to_reach(checkout: Checkout) -> None:
    """No `# syntax=` line: BuildKit's built-in Dockerfile frontend builds it, offline or behind a mirror."""
    with timed("image build (BuildKit)"):
        output = build(checkout, BUILDKIT, buildkit=True)
    assert "docker/dockerfile" not in output and "resolve image config" not in output
    assert checkout.daemon.docker("image", "inspect", BUILDKIT, check=False).returncode == 0


def test_the_classic_builder_builds_an_image_that_runs_as_its_own_user(classic_image: str, checkout: Checkout) -> None:
    ran = checkout.daemon.docker("run", "--rm", "--network", "none", classic_image, "sh", "-c", "id -u; segb --help")
    uid, *usage = ran.stdout.splitlines()
    assert uid == "10001"
    assert usage[0].startswith("usage: segb")


@pytest.fixture
def root_owned_folder() -> Iterator[Path]:
    """A host folder as `mkdir` makes it for root: 0755, writable by root alone."""
    folder = Path(tempfile.mkdtemp(prefix="segb-data-"))
    folder.chmod(0o755)
    assert os.stat(folder).st_uid == 0
    yield folder
    folder.rmdir()


def test_a_root_owned_host_folder_on_data_gets_one_line_saying_what_to_do(
    classic_image: str, checkout: Checkout, root_owned_folder: Path
) -> None:
    ran = checkout.daemon.docker(
        "run", "--rm", "--network", "none", "-v", f"{root_owned_folder}:/data", classic_image, check=False
    )
    assert ran.returncode == 2, ran.stdout + ran.stderr
    assert ran.stderr.splitlines() == [
        "segb: error: DATA_DIR /data is not writable by this server's user, uid 10001 (Permission denied: "
        "/data/logs): give the folder to that user: `sudo chown -R 10001:10001 /data` (for a host folder mounted "
        "on /data in a container, run it on the host folder)"
    ]
    assert list(root_owned_folder.iterdir()) == []
