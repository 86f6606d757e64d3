"""The PostgreSQL override on the real stack: `docker compose -f docker-compose.yaml -f docker-compose.postgres.yaml
up -d --scale backend=2`, the backends' shared state in the postgres service."""

from __future__ import annotations

import pytest

from tests.containers.conftest import timed
from tests.containers.stack import READY, Checkout
from tests.support.docker import DockerDaemon
from tests.support.scenarios import lobby

pytestmark = pytest.mark.containers


def test_two_backends_keep_one_ledger_in_postgres(
    docker_daemon: DockerDaemon, standins: None, tmp_path_factory: pytest.TempPathFactory
) -> None:
    checkout = Checkout(docker_daemon, tmp_path_factory.mktemp("postgres"))
    checkout.configure()
    checkout.files = ("docker-compose.yaml", "docker-compose.postgres.yaml")
    try:
        with timed("postgres override up"):
            checkout.compose("up", "-d", "--scale", "backend=2", timeout=900)
        assert checkout.curl_ready() == READY
        assert len(checkout.containers("backend")) == 2
        responses = lobby().publish_all(checkout.api)
        receipts = checkout.receipts()
        assert receipts == len(responses)
        counted = checkout.compose(
            "exec", "-T", "postgres", "psql", "-U", "segb", "-d", "segb", "-tAc", "SELECT COUNT(*) FROM receipts"
        )
        assert int(counted.stdout) == receipts  # the chain lives in PostgreSQL
        assert checkout.virtuoso_count() > 0
        for container in checkout.containers("backend"):
            assert "Traceback" not in checkout.sh("docker", "logs", container).stderr
    finally:
        with timed("compose down"):
            checkout.compose("down", "-v", check=False)
