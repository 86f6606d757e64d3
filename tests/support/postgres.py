"""A real PostgreSQL (Debian's `postgresql` package) on a free loopback port with a throwaway cluster.

PostgreSQL refuses to run as root; when the tests do, the server runs as the `postgres` account the Debian
package creates, in a temporary directory of its own (pytest's directories are private to root).
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import psycopg

from tests.support.net import free_port
from tests.support.processes import end

INSTALL_HINT = "install Debian's postgresql package (.ci/run does)"


def _binary(name: str) -> str:
    found = shutil.which(name) or next(iter(sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"), reverse=True)), None)
    if found is None:
        raise RuntimeError(f"{name} not found: {INSTALL_HINT}")
    return found


class PostgresProcess:
    """One PostgreSQL server; `url(database)` names a database in it (`create_database` makes one)."""

    def __init__(self) -> None:
        self.port = free_port()
        self.directory = Path(tempfile.mkdtemp(prefix="segb-postgres-"))
        self._account = pwd.getpwnam("postgres") if os.geteuid() == 0 else None
        if self._account is not None:
            os.chown(self.directory, self._account.pw_uid, self._account.pw_gid)
        self._process: subprocess.Popen[bytes] | None = None
        self._run([_binary("initdb"), "-D", str(self.data), "-U", "segb", "--auth=trust", "-E", "UTF8"])

    @property
    def data(self) -> Path:
        return self.directory / "data"

    def url(self, database: str = "postgres") -> str:
        return f"postgresql://segb@127.0.0.1:{self.port}/{database}"

    def start(self) -> None:
        argv = [
            _binary("postgres"), "-D", str(self.data), "-p", str(self.port), "-h", "127.0.0.1",
            "-k", str(self.directory), "-c", "fsync=off", "-c", "max_connections=200",
        ]  # fmt: skip
        log = (self.directory / "postgres.log").open("wb")
        self._process = subprocess.Popen(argv, stdout=log, stderr=log, **self._as_account())
        deadline = time.monotonic() + 60
        while True:
            try:
                psycopg.connect(self.url(), connect_timeout=2).close()
                return
            except psycopg.OperationalError:
                if self._process.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"PostgreSQL did not start: {self.log_tail()}") from None
                time.sleep(0.1)

    def create_database(self, name: str) -> str:
        with psycopg.connect(self.url(), autocommit=True) as connection:
            connection.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def stop(self) -> None:
        if self._process is not None:
            end(self._process, signal.SIGINT)  # "fast" shutdown: SIGTERM's "smart" one waits for clients
        self._process = None

    def remove(self) -> None:
        self.stop()
        shutil.rmtree(self.directory, ignore_errors=True)

    def log_tail(self) -> str:
        log = self.directory / "postgres.log"
        return log.read_text(errors="replace")[-2000:] if log.exists() else ""

    def _as_account(self) -> dict[str, int]:
        if self._account is None:
            return {}
        return {"user": self._account.pw_uid, "group": self._account.pw_gid, "extra_groups": []}

    def _run(self, argv: list[str]) -> None:
        subprocess.run(argv, check=True, capture_output=True, **self._as_account())  # type: ignore[call-overload]
