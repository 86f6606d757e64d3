"""The sockets `segb serve` listens on, opened before anything else starts: a port that is taken is one line
saying which and how to choose another, not uvicorn's bind error followed by the tracebacks of a startup that
had already begun."""

from __future__ import annotations

import errno
import socket
from dataclasses import dataclass


class CannotListen(OSError):
    """A server cannot listen where the settings say; the message says why and what to change."""


@dataclass(frozen=True)
class Listener:
    """Where one of the servers listens, and how a user chooses another port for it."""

    what: str  # "API", "UI"
    host: str
    port: int
    option: str  # the command-line flag
    setting: str  # the environment variable

    def open(self) -> socket.socket:
        """A bound socket (uvicorn listens on it), or CannotListen naming the port and what to do."""
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn binds: restarts reuse the port
        try:
            sock.bind((self.host, self.port))
        except OSError as error:
            sock.close()
            raise CannotListen(self._problem(error)) from None
        sock.set_inheritable(True)
        return sock

    def check(self) -> None:
        """Raise CannotListen now if the port is taken (for servers that bind it themselves a moment later)."""
        self.open().close()

    def _problem(self, error: OSError) -> str:
        where = f"{self.host}:{self.port}"
        choose = f"choose another port with {self.option} or {self.setting}"
        if error.errno == errno.EADDRINUSE:
            return f"the {self.what}'s port {self.port} is already in use ({where}): stop what holds it, or {choose}"
        return f"the {self.what} cannot listen on {where} ({error.strerror or error}): {choose}, or another HOST"
