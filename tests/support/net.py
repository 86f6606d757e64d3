"""Ports for servers started by tests."""

from __future__ import annotations

import random
import socket
import threading

# Below Linux's ephemeral range (32768 to 60999): a port taken from there can be taken again a moment later by
# the local end of any outgoing connection, and a server then fails to start with "Address already in use".
_FIRST, _LAST = 20000, 32767
_handed_out: set[int] = set()
_lock = threading.Lock()


def free_port() -> int:
    """A port no socket holds on any interface, never handed out before in this process."""
    with _lock:
        while True:
            port = random.randint(_FIRST, _LAST)
            if port in _handed_out:
                continue
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
                try:
                    probe.bind(("0.0.0.0", port))
                except OSError:
                    continue
            _handed_out.add(port)
            return port
