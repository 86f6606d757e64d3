"""The README's and the tutorial's commands on the real stack: `cp .env.example .env`, `docker compose up -d`,
the readiness `curl`, a robot publishing through the proxy, the UI, restarts, more backends, `down` and `up`.

The tests go on, in order, from the state the one before left, as a user's session on one stack does.
"""

from __future__ import annotations

import ipaddress
import json
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

import httpx
import pytest
from pyoxigraph import RdfFormat

from tests.containers.conftest import timed
from tests.containers.stack import READY, Checkout
from tests.support.docker import DockerDaemon
from tests.support.graphs import value_triples
from tests.support.scenarios import lobby
from tests.support.settle import settle

pytestmark = pytest.mark.containers

FORGED = "203.0.113.9"  # an address the caller claims in X-Forwarded-For (TEST-NET-3: no real host)


@dataclass
class Tutorial:
    checkout: Checkout
    up: str  # what the first `docker compose up -d` printed
    triples: int = 0  # in Virtuoso's events graph once the robots have published
    receipts: int = 0  # in the ledger by then


@pytest.fixture(scope="module")
def tutorial(
    docker_daemon: DockerDaemon, standins: None, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Tutorial]:
    checkout = Checkout(docker_daemon, tmp_path_factory.mktemp("tutorial"))
    checkout.configure()
    # A new user's first `up`: no segb-server:local yet (another test, or a kept data root, may have built one).
    checkout.sh("docker", "image", "rm", "-f", "segb-server:local")
    try:
        with timed("first compose up"):
            up = checkout.compose("up", "-d", check=False, timeout=900)
        assert up.returncode == 0, up.stdout[-4000:] + up.stderr[-4000:]
        yield Tutorial(checkout, up.stdout + up.stderr)
    finally:
        with timed("compose down"):
            checkout.compose("down", "-v", check=False)


def test_up_builds_the_image_and_pulls_nothing(tutorial: Tutorial) -> None:
    """`pull_policy: build`: compose builds segb-server:local, and never asks a registry for it first."""
    assert "Pulling" not in tutorial.up and "pull access denied" not in tutorial.up
    assert "Built" in tutorial.up
    assert tutorial.checkout.sh("docker", "image", "inspect", "segb-server:local", check=False).returncode == 0


def test_the_readiness_curl_prints_exactly_what_the_readme_shows(tutorial: Tutorial) -> None:
    assert tutorial.checkout.curl_ready() == READY  # right after `up -d` returned


def test_the_api_and_the_ui_are_published_on_this_machine_only(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    for service, port, on_host in (("proxy", 5000, "API_PORT"), ("ui", 8080, "UI_PORT")):
        [container] = checkout.containers(service)
        published = checkout.sh("docker", "port", container).stdout.splitlines()
        assert published == [f"{port}/tcp -> 127.0.0.1:{checkout.env(on_host)}"]


def test_the_backend_says_loudly_that_authentication_is_off(tutorial: Tutorial) -> None:
    log = tutorial.checkout.logs("backend")
    assert "WARNING segb.serve: AUTHENTICATION IS OFF (SECRET_KEY is empty) and the API listens on 0.0.0.0" in log


def logged_origin(checkout: Checkout, marker: str) -> str:
    """origin_ip of the request whose path holds `marker`, from the audit log (GET /logs/server)."""
    answer = httpx.get(f"{checkout.api}/logs/server", params={"contains": marker, "limit": 10}, timeout=30).json()
    [entry] = [entry for entry in answer["entries"] if marker in (entry.get("path") or "")]
    return str(entry["origin_ip"])


def test_the_audit_log_names_the_caller_not_the_address_it_claims(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    through_proxy = f"/reports/{uuid.uuid4().hex}"
    httpx.get(f"{checkout.api}{through_proxy}", headers={"X-Forwarded-For": FORGED}, timeout=30)
    # The proxy sees this machine's connection through Docker's port forwarding: from the network's gateway,
    # the first address of the compose file's subnet.
    network = json.loads(checkout.sh("docker", "network", "inspect", "segb_default").stdout)[0]
    gateway = str(next(ipaddress.ip_network(network["IPAM"]["Config"][0]["Subnet"]).hosts()))
    assert logged_origin(checkout, through_proxy) == gateway

    # Another container on the stack's network, straight to a backend: only the proxy is believed.
    direct = f"/reports/{uuid.uuid4().hex}"
    request = (
        "import urllib.request, urllib.error\n"
        f"request = urllib.request.Request('http://backend:5000{direct}', headers={{'X-Forwarded-For': '{FORGED}'}})\n"
        "try:\n    urllib.request.urlopen(request, timeout=10)\nexcept urllib.error.HTTPError:\n    pass\n"
    )
    checkout.compose("exec", "-T", "ui", "python", "-c", request)
    [ui] = checkout.containers("ui")
    ui_address = json.loads(checkout.sh("docker", "inspect", ui).stdout)[0]["NetworkSettings"]["Networks"]
    assert logged_origin(checkout, direct) == ui_address["segb_default"]["IPAddress"]


def test_the_robot_client_publishes_through_the_proxy_into_virtuoso(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    assert checkout.virtuoso_count() == 0
    scenario = lobby()
    responses = scenario.publish_all(checkout.api)  # the PyPI client, as robots publish
    assert responses and all(response["triples_received"] > 0 for response in responses)
    expected = set().union(*(value_triples(turtle, RdfFormat.TURTLE) for turtle in scenario.published_turtle()))
    tutorial.triples = checkout.virtuoso_count()
    assert tutorial.triples == len(expected)
    tutorial.receipts = checkout.receipts()
    assert tutorial.receipts == len(responses)


def participants_shown(checkout: Checkout) -> str:
    # `up -d` returns once the UI container has started; its server listens a moment later.
    checkout.wait_status(f"{checkout.ui}/health", 200, timeout=60)
    reports = httpx.get(f"{checkout.ui}/reports", timeout=60)
    assert reports.status_code == 200
    return reports.text.split('id="report-participants"', 1)[1].split("</section>", 1)[0]


def test_the_ui_container_shows_the_reports_and_the_graph(tutorial: Tutorial) -> None:
    participants = participants_shown(tutorial.checkout)
    assert "Maria" in participants and "TIAGo" in participants
    graph = httpx.get(f"{tutorial.checkout.ui}/kg-graph", timeout=60)
    assert graph.status_code == 200 and "cytoscape" in graph.text


def assert_nothing_lost(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    checkout.wait_ready()
    settle(checkout.api)
    assert checkout.virtuoso_count() == tutorial.triples
    assert checkout.receipts() == tutorial.receipts
    assert "Maria" in participants_shown(checkout)


def test_a_backend_restart_loses_nothing(tutorial: Tutorial) -> None:
    with timed("backend restart"):
        tutorial.checkout.compose("restart", "backend")
        assert_nothing_lost(tutorial)


def test_virtuoso_away_makes_the_api_unready_and_back_ready_with_everything(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    with timed("virtuoso stop and start"):
        checkout.compose("stop", "virtuoso")
        checkout.wait_status(f"{checkout.api}/healthz/ready", 503)
        checkout.compose("start", "virtuoso")
        assert_nothing_lost(tutorial)


def test_two_backend_containers_share_the_posts(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    with timed("scale backend=2"):
        checkout.compose("up", "-d", "--scale", "backend=2")
        assert len(checkout.containers("backend")) == 2
        checkout.compose("restart", "proxy")  # nginx reads `backend`'s addresses when it starts (deploy/nginx.conf)
        checkout.wait_ready()
    served: dict[str, int] = {}
    for _ in range(5):  # the proxy alternates between the containers
        lobby().publish_all(checkout.api)  # the robots again (the client names some resources anew each time)
        served = {
            container: checkout.sh("docker", "logs", container).stderr.count("method=POST path=/ttl ")
            for container in checkout.containers("backend")
        }
        if all(served.values()):
            break
    assert len(served) == 2 and all(served.values()), served
    settle(checkout.api)
    triples, receipts = checkout.virtuoso_count(), checkout.receipts()
    assert triples > tutorial.triples and receipts > tutorial.receipts
    tutorial.triples, tutorial.receipts = triples, receipts


def test_down_then_up_again_keeps_the_data(tutorial: Tutorial) -> None:
    checkout = tutorial.checkout
    with timed("down and up"):
        checkout.compose("down")
        checkout.compose("up", "-d", timeout=900)
    assert checkout.curl_ready() == READY
    assert len(checkout.containers("backend")) == 1
    assert_nothing_lost(tutorial)


def test_a_changed_virtuoso_password_ends_in_a_message_saying_why(tutorial: Tutorial) -> None:
    """VIRTUOSO_PASSWORD changed once the virtuoso-data volume exists: Virtuoso keeps the first one. `up` fails
    naming the backend, and the backend's log says why and what to do."""
    checkout = tutorial.checkout
    password = checkout.env("VIRTUOSO_PASSWORD")
    checkout.compose("down")
    checkout.set_env(VIRTUOSO_PASSWORD="changed-after-the-volume-was-made")
    with timed("up with a changed password"):
        up = checkout.compose("up", "-d", check=False, timeout=900)
    assert up.returncode != 0
    assert "backend" in up.stderr and "unhealthy" in up.stderr, up.stderr
    assert checkout.health()["virtuoso"] == "healthy"  # it answers; the backend is the one that cannot log in
    log = checkout.logs("backend")
    refused = "ERROR segb.store: store not reachable (virtuoso, attempt 1): Virtuoso refused the password of user dba"
    assert refused in log
    assert "VIRTUOSO_PASSWORD is not that account's password" in log
    assert "when the virtuoso-data volume was created" in log

    checkout.set_env(VIRTUOSO_PASSWORD=password)  # as the message says: the password the volume was made with
    checkout.compose("up", "-d", timeout=900)
    assert_nothing_lost(tutorial)
