"""A thin keep-alive HTTP client for the workloads, so the figures are the server's rather than the client's.

httpx costs about 0.5 ms of client CPU per request on this kind of machine, a quarter of the small-post
target; the standard library's `http.client` costs about a tenth of that. `client_floor` in bench/floor.py
measures what is left (client, loopback, HTTP) against a server that does nothing.
"""

from __future__ import annotations

import http.client
import json
from typing import Any
from urllib.parse import urlsplit


class BenchError(Exception):
    """The server answered a request with an error status."""


class Client:
    """One kept-alive connection; not thread-safe (each robot thread has its own). `connection_per_request`: a
    new connection for every request instead, as the PyPI client's `requests.post` makes one."""

    def __init__(self, url: str, timeout: float = 600, connection_per_request: bool = False) -> None:
        parts = urlsplit(url)
        self._connection = http.client.HTTPConnection(parts.hostname or "127.0.0.1", parts.port, timeout=timeout)
        self._connection_per_request = connection_per_request

    def post(self, path: str, body: bytes, content_type: str) -> bytes:
        """POST `body`; the answer's body, or BenchError on a status of 400 or more."""
        self._connection.request("POST", path, body=body, headers={"Content-Type": content_type})
        response = self._connection.getresponse()
        answer = response.read()
        if self._connection_per_request:
            self._connection.close()  # the next request connects again
        if response.status >= 400:
            raise BenchError(f"POST {path} answered {response.status}: {answer[:300]!r}")
        return answer

    def publish(self, turtle: str) -> dict[str, Any]:
        """What `SEGBPublisher` sends: `{"ttl_content", "user"}` to POST /ttl."""
        body = json.dumps({"ttl_content": turtle, "user": "bench"}).encode()
        return json.loads(self.post("/ttl", body, "application/json"))

    def close(self) -> None:
        self._connection.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
