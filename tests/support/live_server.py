"""Real HTTP servers for tests: uvicorn serving an ASGI app on a free loopback port, in a thread. For what needs a
socket (other processes, browsers, other HTTP libraries, reads that time out); the rest is served in process
(tests/support/in_process.py), with the same `client`, `get` and `post`."""

from __future__ import annotations

import threading
import time
from typing import Any

import httpx
import uvicorn

from tests.support.net import free_port


class LiveServer:
    """`with LiveServer(app) as server:` serves `app` at `server.url` until the block ends; `server.client` is an
    httpx.Client for it."""

    def __init__(self, app: object, port: int | None = None) -> None:
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        config = uvicorn.Config(app, host="127.0.0.1", port=self.port, log_level="warning", lifespan="on")
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, daemon=True)
        self.client = httpx.Client(base_url=self.url, timeout=60)

    def __enter__(self) -> LiveServer:
        self._thread.start()
        deadline = time.monotonic() + 90  # start-up parses every kept query: slow on a busy machine
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError(f"server on port {self.port} did not start")
            time.sleep(0.01)
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.client.close()
        self._server.should_exit = True
        self._thread.join(timeout=20)

    def get(self, path: str, **options: Any) -> httpx.Response:
        return self.client.get(path, **options)

    def post(self, path: str, **options: Any) -> httpx.Response:
        return self.client.post(path, **options)
