"""docker-compose.yaml: valid for compose, every variable in .env.example, and the tutorial holding on its services.

No Docker engine runs here, so the last test runs the services natively with exactly the commands and
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
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.support.compose import (
    COMPOSE_FILE,
    ENV_EXAMPLE,
    ROOT,
    NativeProcess,
    NativeService,
    compose_variables,
    final_stage,
    host_environment,
    image_environment,
    image_healthcheck,
    native_urls,
    read_env_file,
    resolved_compose,
    run_compose_config,
    stage_copies,
    to_native,
    unescape_dollars,
)
from tests.support.net import free_port
from tests.support.scenarios import lobby
from tests.support.virtuoso import VirtuosoProcess

READY = b'{"ready": true, "virtuoso": true}'


@pytest.fixture(scope="module")
def compose(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return resolved_compose(tmp_path_factory.mktemp("compose"))


# --- docker-compose config -----------------------------------------------------------------------------


def test_config_resolves_the_three_services_with_the_example_env(compose: dict[str, Any]) -> None:
    services = compose["services"]
    assert set(services) == {"virtuoso", "backend", "ui"}
    assert services["virtuoso"]["image"] == "openlink/virtuoso-opensource-7:7.2.16"
    assert services["backend"]["image"] == services["ui"]["image"] == "segb-server:local"
    assert "ports" not in services["virtuoso"]  # Virtuoso is reached by the backend only
    assert services["backend"]["ports"] == [{"published": 5000, "target": 5000}]
    assert services["ui"]["ports"] == [{"published": 8080, "target": 8080}]
    assert services["backend"]["depends_on"] == {"virtuoso": {"condition": "service_healthy"}}
    assert services["ui"]["depends_on"] == {"backend": {"condition": "service_healthy"}}
    assert services["virtuoso"]["volumes"] == ["virtuoso-data:/database:rw"]
    assert services["backend"]["volumes"] == ["backend-data:/data:rw"]


def test_config_passes_the_example_env_to_the_containers(compose: dict[str, Any]) -> None:
    example = read_env_file(ENV_EXAMPLE)
    services = compose["services"]
    assert services["virtuoso"]["environment"]["DBA_PASSWORD"] == example["VIRTUOSO_PASSWORD"]
    backend = services["backend"]["environment"]
    assert backend["STORE"] == "virtuoso"
    assert backend["VIRTUOSO_ENDPOINT"] == "http://virtuoso:8890/sparql-auth"
    assert backend["VIRTUOSO_PASSWORD"] == example["VIRTUOSO_PASSWORD"]
    assert backend["SECRET_KEY"] == ""  # auth off in the example
    assert services["ui"]["environment"]["BACKEND_URL"] == "http://backend:5000"
    assert "VIRTUOSO_PASSWORD" not in services["ui"]["environment"]  # the UI holds no store credentials


def test_healthchecks_probe_each_container_s_own_service(compose: dict[str, Any]) -> None:
    services = compose["services"]
    assert "isql 1111 dba" in services["virtuoso"]["healthcheck"]["test"][1]
    # The backend inherits the image's check of :5000/healthz/ready; the UI overrides it with its own port.
    assert "healthcheck" not in services["backend"]
    _, image_check = image_healthcheck(final_stage())
    assert "http://127.0.0.1:5000/healthz/ready" in image_check[-1]
    assert services["backend"]["command"][-2:] == ["--api-port", "5000"]
    ui_check = services["ui"]["healthcheck"]["test"]
    assert "http://127.0.0.1:8080/health" in ui_check[-1]
    assert services["ui"]["command"][-2:] == ["--ui-port", "8080"]


def test_config_without_the_virtuoso_password_fails_naming_it(tmp_path: Path) -> None:
    env = "\n".join(line for line in ENV_EXAMPLE.read_text().splitlines() if not line.startswith("VIRTUOSO_PASSWORD"))
    result = run_compose_config(tmp_path, env)
    assert result.returncode != 0
    assert "set VIRTUOSO_PASSWORD in .env (cp .env.example .env)" in result.stderr


def test_env_example_documents_exactly_the_variables_compose_uses() -> None:
    example = ENV_EXAMPLE.read_text()
    assert compose_variables(COMPOSE_FILE.read_text()) == set(read_env_file(ENV_EXAMPLE))
    for name in read_env_file(ENV_EXAMPLE):
        # each variable comes with a comment somewhere above it in its block
        block = example.split(f"\n{name}=")[0].rsplit("\n\n", 1)[-1]
        assert "#" in block, name


# --- the tutorial, on the compose services run natively ---------------------------------------------------


class NativeStack:
    """The compose services as local processes; ports[(host, container port)] → local port."""

    def __init__(self, compose: dict[str, Any], directory: Path) -> None:
        self.services = compose["services"]
        self.directory = directory
        self.virtuoso = VirtuosoProcess(self._mkdir("virtuoso"), ini_overrides=self.virtuoso_ini())
        self.api_port, self.ui_port = free_port(), free_port()
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

    def ports(self, service: str) -> dict[tuple[str, int], int]:
        """What (host, port) means seen from inside `service`'s container."""
        own = {"backend": (5000, self.api_port), "ui": (8080, self.ui_port)}[service]
        return {
            ("virtuoso", 8890): self.virtuoso.http_port,
            ("backend", 5000): self.api_port,
            ("ui", 8080): self.ui_port,
            ("127.0.0.1", own[0]): own[1],
        }

    def container_root(self, service: str) -> Path:
        """A directory standing for the container's `/`: the image's files (COPY of the final stage), the
        working directory and the volumes."""
        root = self._mkdir(f"{service}-root")
        for sources, destination in stage_copies(final_stage()):
            for source in sources:
                shutil.copytree(ROOT / source, root / destination.lstrip("/"), dirs_exist_ok=True)
        (root / "data").mkdir(exist_ok=True)
        return root

    def native(self, service: str) -> tuple[NativeService, Path]:
        """The service as compose would run it in the image (image ENV, then the service's), made native."""
        config = self.services[service]
        image_env = {name: value for name, value in image_environment(final_stage()).items() if name != "PATH"}
        environment = {**image_env, **{name: str(value) for name, value in config["environment"].items()}}
        root = self.container_root(service)
        native = to_native(service, config["command"], environment, ports=self.ports(service), root=root)
        changed_arguments = [old for old, new in zip(config["command"], native.command, strict=True) if old != new]
        changed_variables = {name for name in environment if native.environment[name] != environment[name]}
        self.changes[service] = (changed_arguments, changed_variables)
        full = NativeService(native.command, {**native.environment, **host_environment(root)})
        workdir = next(i.arguments for i in final_stage() if i.keyword == "WORKDIR")
        return full, root / workdir.lstrip("/")

    def start(self, service: str, stack: ExitStack) -> NativeProcess:
        native, workdir = self.native(service)
        workdir.mkdir(parents=True, exist_ok=True)
        process = NativeProcess(service, native, cwd=workdir, log_dir=self.directory)
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


@pytest.mark.virtuoso
def test_tutorial_holds_on_the_compose_services_run_natively(native_stack: NativeStack) -> None:
    stack = native_stack
    with ExitStack() as running:
        # virtuoso: started as the image would be, with DBA_PASSWORD as the dba password; compose waits for
        # its healthcheck before starting the backend.
        stack.virtuoso.start()
        running.callback(stack.virtuoso.stop)
        assert run_virtuoso_healthcheck(stack).returncode != 0  # still the fresh database's password
        stack.virtuoso.set_dba_password(stack.services["virtuoso"]["environment"]["DBA_PASSWORD"])
        assert run_virtuoso_healthcheck(stack).returncode == 0

        backend = stack.start("backend", running)
        api = f"http://localhost:{stack.api_port}"
        assert backend.wait_for(f"{api}/healthz/ready").content == READY
        _, image_check = image_healthcheck(final_stage())
        backend_check = run_healthcheck(image_check, stack, "backend")
        assert backend_check.returncode == 0, backend_check.stderr

        ui = stack.start("ui", running)  # compose starts it once the backend is healthy
        ui_url = f"http://localhost:{stack.ui_port}"
        ui.wait_for(f"{ui_url}/health")
        ui_test = stack.services["ui"]["healthcheck"]["test"]
        assert ui_test[0] == "CMD"
        ui_check = run_healthcheck(ui_test[1:], stack, "ui")
        assert ui_check.returncode == 0, ui_check.stderr

        # The only differences from what compose runs: ports, the service hostnames, the container paths.
        assert stack.changes["backend"] == (["5000"], {"VIRTUOSO_ENDPOINT", "DATA_DIR"})
        assert stack.changes["ui"] == (["8080"], {"BACKEND_URL", "DATA_DIR"})

        # The tutorial: curl -s http://localhost:5000/healthz/ready
        curl = shutil.which("curl")
        assert curl is not None, "curl not found: install Debian's curl (scripts/test.sh does)"
        printed = subprocess.run([curl, "-s", f"{api}/healthz/ready"], capture_output=True, timeout=30).stdout
        assert printed == READY

        assert "Maria" not in httpx.get(f"{ui_url}/reports", timeout=30).text
        responses = lobby().publish_all(api)  # the PyPI client, as robots publish
        assert responses and all(response["triples_received"] > 0 for response in responses)
        reports = httpx.get(f"{ui_url}/reports", timeout=30)
        assert reports.status_code == 200
        participants = reports.text.split('id="report-participants"', 1)[1].split("</section>", 1)[0]
        assert "Maria" in participants and "TIAGo" in participants
        graph = httpx.get(f"{ui_url}/kg-graph", timeout=30)
        assert graph.status_code == 200 and "cytoscape" in graph.text

        assert "store reachable (virtuoso)" in backend.output()
        assert ui.stop() == 0 and backend.stop() == 0
    assert "Traceback" not in backend.output() + ui.output()
