"""docker-compose.yaml: valid for compose, every variable in .env.example, and the tutorial holding on its services.

The container tier (tests/containers) runs the stack itself on a Docker daemon; these tests are its fast
companions, and need no daemon. The last ones run the services natively with exactly the commands and
environment `docker-compose config` resolves (plus the image's ENV from the Dockerfile), changed only by
`tests.support.compose.to_native`, which stands in for Docker's network and volumes: service names in URLs
become 127.0.0.1, absolute paths move under a directory standing for the container's `/`, and the ports
are free loopback ports mapped from the container ports (5000, 8080, 8890), so the test never collides with
a server already running on this machine. The tutorial's `curl` then goes to the port standing for the
published one.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass
from ipaddress import ip_address, ip_network
from pathlib import Path
from typing import Any

import httpx
import psycopg
import pytest
import yaml

from tests.support.compose import (
    COMPOSE_FILE,
    ENV_EXAMPLE,
    NGINX_CONF,
    POSTGRES_OVERRIDE,
    ROOT,
    NativeProcess,
    NativeService,
    compose_variables,
    final_stage,
    host_environment,
    image_environment,
    image_healthcheck,
    native_nginx_conf,
    native_urls,
    read_env_file,
    resolved_compose,
    run_compose_config,
    stage_copies,
    to_native,
    unescape_dollars,
)
from tests.support.net import free_port
from tests.support.postgres import PostgresProcess
from tests.support.scenarios import lobby
from tests.support.virtuoso import VirtuosoProcess

READY = b'{"ready": true, "virtuoso": true}'


@pytest.fixture(scope="module")
def compose(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return resolved_compose(tmp_path_factory.mktemp("compose"))


# --- docker-compose config -----------------------------------------------------------------------------


HEALTHY = {"condition": "service_healthy"}


@pytest.mark.processes  # docker-compose config
def test_config_resolves_the_four_services_with_the_example_env(compose: dict[str, Any]) -> None:
    services = compose["services"]
    assert set(services) == {"virtuoso", "backend", "proxy", "ui"}
    assert services["virtuoso"]["image"] == "openlink/virtuoso-opensource-7:7.2.16"
    assert services["backend"]["image"] == services["ui"]["image"] == "segb-server:local"
    assert services["proxy"]["image"] == "nginx:1.27-alpine"
    assert "ports" not in services["virtuoso"]  # Virtuoso is reached by the backend only
    # The backend is published through the proxy only and names no container: `--scale backend=N` works.
    assert "ports" not in services["backend"] and "container_name" not in services["backend"]
    # Published on this machine's loopback only, unless PUBLISH_ADDRESS says otherwise.
    assert services["proxy"]["ports"] == ["127.0.0.1:5000:5000/tcp"]
    assert services["ui"]["ports"] == ["127.0.0.1:8080:8080/tcp"]
    # Built by `up`, never pulled: no registry has segb-server:local.
    assert services["backend"]["pull_policy"] == services["ui"]["pull_policy"] == "build"
    assert services["backend"]["depends_on"] == {"virtuoso": HEALTHY}
    assert services["proxy"]["depends_on"] == {"backend": HEALTHY}
    assert services["ui"]["depends_on"] == {"proxy": HEALTHY}
    assert services["virtuoso"]["volumes"] == ["virtuoso-data:/database:rw"]
    assert services["backend"]["volumes"] == ["backend-data:/data:rw"]  # shared by every backend container
    [mount] = services["proxy"]["volumes"]
    source, target, mode = mount.split(":")
    assert (Path(source).relative_to(Path(source).parents[1]), target, mode) == (
        Path("deploy/nginx.conf"),
        "/etc/nginx/nginx.conf",
        "ro",
    )
    assert NGINX_CONF.is_file()


@pytest.mark.processes  # docker-compose config
def test_config_passes_the_example_env_to_the_containers(compose: dict[str, Any]) -> None:
    example = read_env_file(ENV_EXAMPLE)
    services = compose["services"]
    assert services["virtuoso"]["environment"]["DBA_PASSWORD"] == example["VIRTUOSO_PASSWORD"]
    backend = services["backend"]["environment"]
    assert backend["STORE"] == "virtuoso"
    assert backend["VIRTUOSO_ENDPOINT"] == "http://virtuoso:8890/sparql-auth"
    assert backend["VIRTUOSO_PASSWORD"] == example["VIRTUOSO_PASSWORD"]
    assert backend["SECRET_KEY"] == ""  # auth off in the example
    # The backend believes the X-Forwarded-For of the proxy's fixed address only, inside the stack's own subnet.
    proxy_address = services["proxy"]["networks"]["default"]["ipv4_address"]
    assert backend["FORWARDED_ALLOW_IPS"] == proxy_address
    [addresses] = compose["networks"]["default"]["ipam"]["config"]
    assert ip_address(proxy_address) in ip_network(addresses["subnet"])
    assert ip_address(proxy_address) not in ip_network(addresses["ip_range"])  # never given to another container
    assert "STATE_URL" not in backend  # SQLite in the shared volume unless docker-compose.postgres.yaml is added
    assert services["ui"]["environment"]["BACKEND_URL"] == "http://proxy:5000"
    assert "VIRTUOSO_PASSWORD" not in services["ui"]["environment"]  # the UI holds no store credentials


@pytest.mark.processes  # docker-compose config
def test_healthchecks_probe_each_container_s_own_service(compose: dict[str, Any]) -> None:
    services = compose["services"]
    assert "isql 1111 dba" in services["virtuoso"]["healthcheck"]["test"][1]
    # The backend inherits the image's check of :5000/healthz/ready; the UI overrides it with its own port.
    assert "healthcheck" not in services["backend"]
    _, image_check = image_healthcheck(final_stage())
    assert "http://127.0.0.1:5000/healthz/ready" in image_check[-1]
    assert services["backend"]["command"][-2:] == ["--api-port", "5000"]
    assert services["proxy"]["healthcheck"]["test"][-1] == "http://127.0.0.1:5000/healthz/ready"
    ui_check = services["ui"]["healthcheck"]["test"]
    assert "http://127.0.0.1:8080/health" in ui_check[-1]
    assert services["ui"]["command"][-2:] == ["--ui-port", "8080"]


@pytest.mark.processes  # docker-compose config
def test_the_postgres_override_moves_the_state_to_a_postgres_service(compose: dict[str, Any], tmp_path: Path) -> None:
    services = resolved_compose(tmp_path, (COMPOSE_FILE, POSTGRES_OVERRIDE))["services"]
    assert set(services) == {"virtuoso", "backend", "proxy", "ui", "postgres"}
    password = read_env_file(ENV_EXAMPLE)["POSTGRES_PASSWORD"]
    assert services["postgres"]["image"] == "postgres:17-alpine"
    assert services["postgres"]["environment"] == {"POSTGRES_USER": "segb", "POSTGRES_DB": "segb",
                                                   "POSTGRES_PASSWORD": password}  # fmt: skip
    assert "ports" not in services["postgres"]
    assert services["postgres"]["healthcheck"]["test"] == ["CMD", "pg_isready", "-U", "segb", "-d", "segb"]
    backend = services["backend"]
    assert backend["environment"]["STATE_URL"] == f"postgresql://segb:{password}@postgres:5432/segb"
    assert backend["depends_on"] == {"virtuoso": HEALTHY, "postgres": HEALTHY}
    assert "ports" not in backend and backend["command"] == compose["services"]["backend"]["command"]


@pytest.mark.processes  # docker-compose config
def test_the_postgres_override_without_its_password_fails_naming_it(tmp_path: Path) -> None:
    env = "\n".join(line for line in ENV_EXAMPLE.read_text().splitlines() if not line.startswith("POSTGRES_PASSWORD"))
    result = run_compose_config(tmp_path, env, (COMPOSE_FILE, POSTGRES_OVERRIDE))
    assert result.returncode != 0
    assert "set POSTGRES_PASSWORD in .env to use docker-compose.postgres.yaml" in result.stderr


@pytest.mark.processes  # docker-compose config
def test_config_publishes_on_the_address_chosen_in_the_env(tmp_path: Path) -> None:
    env = ENV_EXAMPLE.read_text().replace("PUBLISH_ADDRESS=127.0.0.1", "PUBLISH_ADDRESS=0.0.0.0")
    result = run_compose_config(tmp_path, env)
    assert result.returncode == 0, result.stderr
    services = yaml.safe_load(result.stdout)["services"]
    assert services["proxy"]["ports"] == ["0.0.0.0:5000:5000/tcp"]
    assert services["ui"]["ports"] == ["0.0.0.0:8080:8080/tcp"]


@pytest.mark.processes  # docker-compose config
def test_config_without_the_virtuoso_password_fails_naming_it(tmp_path: Path) -> None:
    env = "\n".join(line for line in ENV_EXAMPLE.read_text().splitlines() if not line.startswith("VIRTUOSO_PASSWORD"))
    result = run_compose_config(tmp_path, env)
    assert result.returncode != 0
    assert "set VIRTUOSO_PASSWORD in .env (cp .env.example .env)" in result.stderr


def test_env_example_documents_exactly_the_variables_compose_uses() -> None:
    example = ENV_EXAMPLE.read_text()
    used = compose_variables(COMPOSE_FILE.read_text() + POSTGRES_OVERRIDE.read_text())
    assert used == set(read_env_file(ENV_EXAMPLE))
    for name in read_env_file(ENV_EXAMPLE):
        # each variable comes with a comment somewhere above it in its block
        block = example.split(f"\n{name}=")[0].rsplit("\n\n", 1)[-1]
        assert "#" in block, name


# --- the tutorial, on the compose services run natively ---------------------------------------------------


class NativeStack:
    """The compose services as local processes; ports[(host, container port)] → local port. `backends`
    containers of the backend service (`--scale backend=N`) share one data volume, as compose's do; a
    PostgreSQL server stands for the postgres service when the override adds it."""

    def __init__(
        self, compose: dict[str, Any], directory: Path, *, backends: int = 1, postgres: PostgresProcess | None = None
    ) -> None:
        self.services = compose["services"]
        self.directory = directory
        self.virtuoso = VirtuosoProcess(self._mkdir("virtuoso"), ini_overrides=self.virtuoso_ini())
        self.postgres = postgres
        self.backend_ports = [free_port() for _ in range(backends)]
        self.proxy_port, self.ui_port = free_port(), free_port()  # the proxy's port stands for the published 5000
        self.changes: dict[str, tuple[list[str], set[str]]] = {}

    def _mkdir(self, name: str) -> Path:
        path = self.directory / name
        path.mkdir(parents=True, exist_ok=True)
        return path

    def virtuoso_ini(self) -> dict[tuple[str, str], str]:
        """The image's VIRT_<Section>_<Key> variables, as virtuoso.ini settings."""
        environment = self.services["virtuoso"]["environment"]
        return {
            tuple(name.removeprefix("VIRT_").split("_", 1)): str(value)  # type: ignore[misc]
            for name, value in environment.items()
            if name.startswith("VIRT_")
        }

    def ports(self, service: str, replica: int = 0) -> dict[tuple[str, int], int]:
        """What (host, port) means seen from inside `service`'s container (its `replica`th, for the backend).
        Inside compose's network `backend` names every backend container; a client reaches one of them."""
        own = {"backend": (5000, self.backend_ports[replica]), "proxy": (5000, self.proxy_port),
               "ui": (8080, self.ui_port)}[service]  # fmt: skip
        ports = {
            ("virtuoso", 8890): self.virtuoso.http_port,
            ("backend", 5000): self.backend_ports[0],
            ("proxy", 5000): self.proxy_port,
            ("ui", 8080): self.ui_port,
            ("127.0.0.1", own[0]): own[1],
            (service, own[0]): own[1],  # its own port flag (--api-port 5000) names this container's port
        }
        if self.postgres is not None:
            ports[("postgres", 5432)] = self.postgres.port
        return ports

    def container_root(self, service: str) -> Path:
        """A directory standing for the container's `/`: the image's files (COPY of the final stage), the
        working directory and the volumes (one per service: its containers share it, as compose's volume)."""
        root = self._mkdir(f"{service}-root")
        for sources, destination in stage_copies(final_stage()):
            for source in sources:
                shutil.copytree(ROOT / source, root / destination.lstrip("/"), dirs_exist_ok=True)
        (root / "data").mkdir(exist_ok=True)
        return root

    def native(self, service: str, replica: int = 0) -> tuple[NativeService, Path]:
        """The service as compose would run it in the image (image ENV, then the service's), made native."""
        config = self.services[service]
        image_env = {name: value for name, value in image_environment(final_stage()).items() if name != "PATH"}
        environment = {**image_env, **{name: str(value) for name, value in config["environment"].items()}}
        root = self.container_root(service)
        ports = self.ports(service, replica)
        native = to_native(service, config["command"], environment, ports=ports, root=root)
        changed_arguments = [old for old, new in zip(config["command"], native.command, strict=True) if old != new]
        changed_variables = {name for name in environment if native.environment[name] != environment[name]}
        self.changes[service] = (changed_arguments, changed_variables)
        full = NativeService(native.command, {**native.environment, **host_environment(root)})
        workdir = next(i.arguments for i in final_stage() if i.keyword == "WORKDIR")
        return full, root / workdir.lstrip("/")

    def start(self, service: str, stack: ExitStack, replica: int = 0) -> NativeProcess:
        native, workdir = self.native(service, replica)
        workdir.mkdir(parents=True, exist_ok=True)
        process = NativeProcess(f"{service}-{replica}", native, cwd=workdir, log_dir=self.directory)
        stack.callback(process.stop)
        return process

    def start_proxy(self, stack: ExitStack) -> NativeProcess:
        """The official nginx image's process with deploy/nginx.conf where compose mounts it, natively:
        Debian's nginx, in front of every backend container."""
        [mount] = self.services["proxy"]["volumes"]
        source, target, _ = mount.split(":")
        assert Path(source).name == NGINX_CONF.name and target == "/etc/nginx/nginx.conf"
        root = self._mkdir("proxy-root")
        (root / "tmp").mkdir(exist_ok=True)
        conf = root / target.lstrip("/")
        conf.parent.mkdir(parents=True, exist_ok=True)
        upstream = {"backend": self.backend_ports}
        conf.write_text(native_nginx_conf(NGINX_CONF.read_text(), listen=self.proxy_port, upstream=upstream, root=root))
        nginx = shutil.which("nginx") or "/usr/sbin/nginx"
        assert Path(nginx).exists(), "nginx not found: install Debian's nginx (scripts/test.sh does)"
        command = NativeService([nginx, "-p", str(root), "-c", str(conf), "-g", "daemon off;"], host_environment(root))
        process = NativeProcess("proxy", command, cwd=root, log_dir=self.directory)
        stack.callback(process.stop)
        return process


@pytest.fixture
def native_stack(compose: dict[str, Any], tmp_path: Path) -> Iterator[NativeStack]:
    yield NativeStack(compose, tmp_path)


def run_virtuoso_healthcheck(stack: NativeStack) -> subprocess.CompletedProcess[bytes]:
    """Compose's check of the virtuoso service, where Debian names the SQL client isql-vt."""
    test = stack.services["virtuoso"]["healthcheck"]["test"]
    assert test[0] == "CMD-SHELL" and "isql 1111 " in test[1]
    shell = unescape_dollars(test[1]).replace("isql 1111 ", f"isql-vt {stack.virtuoso.sql_port} ")
    password = stack.services["virtuoso"]["environment"]["DBA_PASSWORD"]
    env = {**host_environment(stack.directory), "DBA_PASSWORD": password}
    return subprocess.run(["sh", "-c", shell], env=env, capture_output=True, timeout=30)


def run_healthcheck(command: list[str], stack: NativeStack, service: str) -> subprocess.CompletedProcess[bytes]:
    native = [native_urls(argument, stack.ports(service)) for argument in command]
    assert [old for old, new in zip(command, native, strict=True) if old != new] == [command[-1]]
    return subprocess.run(native, env=host_environment(stack.directory), capture_output=True, timeout=30)


@dataclass
class RunningStack:
    backends: list[NativeProcess]
    proxy: NativeProcess
    ui: NativeProcess
    api: str  # the published API port, as the tutorial's curl reaches it
    ui_url: str


def assert_no_traceback(output: str) -> None:
    """A service's log holds no traceback; one it holds is shown whole (an assertion's diff would cut it short)."""
    at = output.find("Traceback")
    assert at < 0, "the service logged a traceback:\n" + output[max(0, at - 1000) : at + 8000]


def bring_up(stack: NativeStack, running: ExitStack) -> RunningStack:
    """Every service in compose's order, each once the one it depends on is healthy (by its own check)."""
    # virtuoso: started as the image would be, with DBA_PASSWORD as the dba password.
    assert run_virtuoso_healthcheck(stack).returncode != 0  # not started: unhealthy
    stack.virtuoso.start()
    running.callback(stack.virtuoso.stop)
    # Still the fresh database's password: Virtuoso answers, refusing it, and the check says so (the backend's
    # log says more); healthy, so that the backend starts and can say why it cannot log in.
    refused = run_virtuoso_healthcheck(stack)
    assert (refused.returncode, b"Virtuoso refused DBA_PASSWORD" in refused.stdout) == (0, True)
    stack.virtuoso.set_dba_password(stack.services["virtuoso"]["environment"]["DBA_PASSWORD"])
    accepted = run_virtuoso_healthcheck(stack)
    assert (accepted.returncode, accepted.stdout) == (0, b"")

    backends = [stack.start("backend", running, replica) for replica in range(len(stack.backend_ports))]
    _, image_check = image_healthcheck(final_stage())
    for replica, backend in enumerate(backends):
        assert backend.wait_for(f"http://localhost:{stack.backend_ports[replica]}/healthz/ready").content == READY
        native = [native_urls(argument, stack.ports("backend", replica)) for argument in image_check]
        checked = subprocess.run(native, env=host_environment(stack.directory), capture_output=True, timeout=30)
        assert checked.returncode == 0, checked.stderr

    proxy = stack.start_proxy(running)
    api = f"http://localhost:{stack.proxy_port}"
    assert proxy.wait_for(f"{api}/healthz/ready").content == READY
    proxy_check = run_healthcheck(stack.services["proxy"]["healthcheck"]["test"][1:], stack, "proxy")
    assert proxy_check.returncode == 0, proxy_check.stderr

    ui = stack.start("ui", running)  # compose starts it once the proxy is healthy
    ui_url = f"http://localhost:{stack.ui_port}"
    ui.wait_for(f"{ui_url}/health")
    ui_test = stack.services["ui"]["healthcheck"]["test"]
    assert ui_test[0] == "CMD"
    ui_check = run_healthcheck(ui_test[1:], stack, "ui")
    assert ui_check.returncode == 0, ui_check.stderr
    return RunningStack(backends, proxy, ui, api, ui_url)


def participants_shown(ui_url: str) -> str:
    reports = httpx.get(f"{ui_url}/reports", timeout=30)
    assert reports.status_code == 200
    return reports.text.split('id="report-participants"', 1)[1].split("</section>", 1)[0]


@pytest.mark.virtuoso
def test_tutorial_holds_on_the_compose_services_run_natively(native_stack: NativeStack) -> None:
    stack = native_stack
    with ExitStack() as running:
        up = bring_up(stack, running)
        # The only differences from what compose runs: ports, the service hostnames, the container paths.
        assert stack.changes["backend"] == (["5000"], {"VIRTUOSO_ENDPOINT", "DATA_DIR"})
        assert stack.changes["ui"] == (["8080"], {"BACKEND_URL", "DATA_DIR"})

        # The tutorial: curl -s http://localhost:5000/healthz/ready (the proxy, in front of the backend)
        curl = shutil.which("curl")
        assert curl is not None, "curl not found: install Debian's curl (scripts/test.sh does)"
        printed = subprocess.run([curl, "-s", f"{up.api}/healthz/ready"], capture_output=True, timeout=30).stdout
        assert printed == READY

        assert "Maria" not in participants_shown(up.ui_url)
        responses = lobby().publish_all(up.api)  # the PyPI client, as robots publish
        assert responses and all(response["triples_received"] > 0 for response in responses)
        participants = participants_shown(up.ui_url)
        assert "Maria" in participants and "TIAGo" in participants
        graph = httpx.get(f"{up.ui_url}/kg-graph", timeout=30)
        assert graph.status_code == 200 and "cytoscape" in graph.text
        # The proxy streams: a too-large post gets the API's own JSON 413, not nginx's page.
        too_large = httpx.post(f"{up.api}/ttl", content=b"x" * (64 * 1024 * 1024 + 1),
                               headers={"Content-Type": "text/turtle"}, timeout=60)  # fmt: skip
        assert too_large.status_code == 413 and too_large.json()["error"] == "payload_too_large"

        [backend] = up.backends
        assert "store reachable (virtuoso)" in backend.output()
        assert up.ui.stop() == 0 and up.proxy.stop() == 0 and backend.stop() == 0
    assert_no_traceback(backend.output() + up.ui.output())


def _post_one(api: str, name: str) -> None:
    """One small post on a connection of its own."""
    turtle = f'<https://example.org/robots/spread/{name}> <http://schema.org/name> "{name}" .'
    answer = httpx.post(f"{api}/ttl", json={"ttl_content": turtle}, timeout=60)
    assert answer.status_code == 201, answer.text


@pytest.mark.virtuoso
@pytest.mark.postgres
def test_scaled_backends_with_the_state_in_postgres_run_natively(tmp_path: Path, postgres: PostgresProcess) -> None:
    """`docker compose -f docker-compose.yaml -f docker-compose.postgres.yaml up -d --scale backend=2`."""
    (tmp_path / "compose").mkdir()
    compose = resolved_compose(tmp_path / "compose", (COMPOSE_FILE, POSTGRES_OVERRIDE))
    postgres.create_database(compose["services"]["postgres"]["environment"]["POSTGRES_DB"])
    stack = NativeStack(compose, tmp_path / "stack", backends=2, postgres=postgres)
    with ExitStack() as running:
        up = bring_up(stack, running)
        assert stack.changes["backend"] == (["5000"], {"VIRTUOSO_ENDPOINT", "DATA_DIR", "STATE_URL"})

        published = lobby().publish_all(up.api)
        published += [*lobby().publish_all(up.api)]  # re-published: nothing new, nothing lost
        assert len(published) >= 2
        participants = participants_shown(up.ui_url)
        assert "Maria" in participants and "TIAGo" in participants

        # Both containers took posts through the proxy; the state they share is one valid chain.
        entries = httpx.get(f"{up.api}/logs/server", params={"limit": 2000, "contains": "/ttl"}, timeout=30).json()
        serving = {entry["process"] for entry in entries["entries"] if entry.get("path") == "/ttl"}
        for round_ in range(20):  # more posts until the proxy spread them (it alternates; a worker picks within)
            if len(serving) >= 3:
                break
            # Side by side: posts one after another may all be taken by the worker that accepted the last one.
            with ThreadPoolExecutor(8) as pool:
                list(pool.map(_post_one, [up.api] * 16, [f"{round_}-{n}" for n in range(16)]))
            entries = httpx.get(f"{up.api}/logs/server", params={"limit": 2000, "contains": "/ttl"}, timeout=30)
            serving = {entry["process"] for entry in entries.json()["entries"] if entry.get("path") == "/ttl"}
        assert len(serving) >= 3, f"posts were served by {serving}: two containers of two workers each expected"
        verified = httpx.get(f"{up.api}/ledger/verify", params={"deep": "true"}, timeout=60).json()
        assert verified["valid"] is True and verified["receipts"] >= len(published)
        with psycopg.connect(postgres.url("segb")) as connection:
            kept = connection.execute("SELECT COUNT(*) FROM receipts").fetchone()[0]
        assert kept == verified["receipts"]  # the chain lives in PostgreSQL
        assert not (stack.directory / "backend-root" / "data" / "journal.sqlite3").exists()
        for backend in up.backends:
            assert_no_traceback(backend.output())
