"""Stand-ins for the registry images the stack names, made on this machine for the container tests only.

No image registry is reachable where the tests run. So the tests make a Debian base with debootstrap (from the
mirror apt uses, the host's CA certificates trusted), build on it the stand-ins of tests/containers/standins/
(Debian's Python, Virtuoso, nginx and PostgreSQL, with entrypoints that behave as the official images' do
where the compose files rely on them), and tag each with the name the Dockerfile and the compose files use.
What a test shows about the behaviour of those images themselves holds for the stand-ins only
(tests/containers/README.md says which results those are).
"""

from __future__ import annotations

import functools
import re
import shutil
import subprocess
import sys
import threading
import time
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import yaml

from tests.support.compose import COMPOSE_FILE, POSTGRES_OVERRIDE, ROOT
from tests.support.docker import DockerDaemon, docker_cli

STANDINS = ROOT / "tests" / "containers" / "standins"
BASE = "segb-test/debian:bookworm"
SUITE = "bookworm"  # the Debian release of python:3.11-slim and of the tests' machines


def standin(name: str) -> str:
    """The test's own tag of a stand-in (it also carries the registry name it stands for)."""
    return f"segb-test/{name}"


def registry_names() -> dict[str, str]:
    """Each stand-in's folder → the image it stands for, as the Dockerfile and the compose files name it."""
    default_base = re.search(r"^ARG PYTHON_IMAGE=(\S+)$", (ROOT / "Dockerfile").read_text(), re.MULTILINE)
    assert default_base, "the Dockerfile names its base in ARG PYTHON_IMAGE"
    services = yaml.safe_load(COMPOSE_FILE.read_text())["services"]
    postgres = yaml.safe_load(POSTGRES_OVERRIDE.read_text())["services"]["postgres"]
    return {
        "python": default_base.group(1),
        "virtuoso": services["virtuoso"]["image"],
        "nginx": services["proxy"]["image"],
        "postgres": postgres["image"],
    }


def debian_mirror() -> str:
    """The Debian archive apt uses on this machine (deb822 `URIs:` or one-line `deb` entries)."""
    sources = [Path("/etc/apt/sources.list"), *sorted(Path("/etc/apt/sources.list.d").glob("*"))]
    for path in sources:
        if not path.is_file() or path.suffix not in (".list", ".sources"):
            continue
        for url in re.findall(r"^(?:URIs:|deb(?:\s+\[[^]]*\])?)\s+(\S+)", path.read_text(), re.MULTILINE):
            if url.rstrip("/").endswith("/debian"):
                return url
    return "http://deb.debian.org/debian"


def make_base(daemon: DockerDaemon, directory: Path) -> None:
    """debootstrap's minimal Debian, trusting the host's own CA certificates, imported as BASE."""
    if daemon.docker("image", "inspect", BASE, check=False).returncode == 0:
        return  # kept in a data root that outlives the run (SEGB_CONTAINER_CACHE)
    rootfs = directory / "rootfs"
    bootstrap = ["debootstrap", "--variant=minbase", "--include=ca-certificates", SUITE, str(rootfs), debian_mirror()]
    made = subprocess.run(bootstrap, capture_output=True, text=True, timeout=1200)
    assert made.returncode == 0, f"debootstrap failed:\n{made.stdout[-3000:]}\n{made.stderr[-3000:]}"
    for certificate in Path("/usr/local/share/ca-certificates").glob("*.crt"):
        shutil.copy(certificate, rootfs / "usr" / "local" / "share" / "ca-certificates")
    subprocess.run(["chroot", str(rootfs), "update-ca-certificates"], check=True, capture_output=True, timeout=120)
    for cache in ("var/cache/apt/archives", "var/lib/apt/lists"):
        for path in (rootfs / cache).glob("*"):
            if path.is_file():
                path.unlink()
    script = 'tar --numeric-owner -C "$1" -c . | "$2" import -c \'CMD ["bash"]\' - "$3"'
    daemon.run(["sh", "-c", script, "sh", str(rootfs), docker_cli() or "docker", BASE], timeout=600)
    shutil.rmtree(rootfs)


def build_standins(daemon: DockerDaemon, mirror: PackageMirror) -> dict[str, float]:
    """Build every stand-in on BASE and tag it with its own and its registry name; seconds each took."""
    seconds = {}
    for name, registry_name in registry_names().items():
        arguments = ["--build-arg", f"BASE={BASE}", "-t", standin(name), "-t", registry_name]
        if name == "python":
            arguments += ["--build-arg", f"PACKAGE_INDEX={mirror.url}", "--build-arg", f"PACKAGE_HOST={mirror.host}"]
        started = time.monotonic()
        # The classic builder, on the host's network: apt downloads from the mirror as the host does.
        classic = {"DOCKER_BUILDKIT": "0"}
        daemon.docker("build", "-q", "--network", "host", *arguments, str(STANDINS / name), env=classic)
        seconds[name] = time.monotonic() - started
    return seconds


class _QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        pass  # one line per file pip fetches: noise in the tests' output


class PackageMirror:
    """The files requirements.lock pins, for Python 3.11 on this platform, downloaded through the host's own
    network and served on the daemon's bridge: what the stand-in Python's pip installs from. It holds the
    lock's files and nothing else, so a build that needs anything more fails."""

    def __init__(self, directory: Path, host: str) -> None:
        self.directory = directory
        self.host = host
        self._server: ThreadingHTTPServer | None = None

    @property
    def url(self) -> str:
        assert self._server is not None
        return f"http://{self.host}:{self._server.server_port}/"

    def start(self) -> None:
        download = [sys.executable, "-m", "pip", "download", "-q", "--disable-pip-version-check"]
        download += ["--require-hashes", "--no-deps", "--only-binary=:all:", "--python-version", "3.11"]
        download += ["-r", str(ROOT / "requirements.lock"), "-d", str(self.directory)]
        fetched = subprocess.run(download, capture_output=True, text=True, timeout=600)
        assert fetched.returncode == 0, f"downloading requirements.lock failed:\n{fetched.stderr[-3000:]}"
        handler = functools.partial(_QuietHandler, directory=str(self.directory))
        self._server = ThreadingHTTPServer((self.host, 0), handler)
        threading.Thread(target=self._server.serve_forever, name="package-mirror", daemon=True).start()

    def stop(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
