"""A webhook receiver on a free loopback port: it checks each delivery's signature, refuses the first ones it is
told to (500), and keeps what it accepted."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from segb_server.backend.services.observability.signing import HEADER, verified
from tests.support.net import free_port


class Receiver:
    def __init__(self, secret: str, refuse_first: int = 0) -> None:
        self.secret = secret
        self.refusals_left = refuse_first
        self.accepted: list[dict[str, object]] = []
        self.attempts: list[str] = []  # every delivery id as it came, refused ones included
        self.bad_signatures = 0
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}/hook"
        self._lock = threading.Lock()
        self._server = ThreadingHTTPServer(("127.0.0.1", self.port), self._handler())
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)

    def __enter__(self) -> Receiver:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._server.shutdown()
        self._server.server_close()

    def wait_for(self, count: int, timeout: float = 30) -> list[dict[str, object]]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if len(self.accepted) >= count:
                    return list(self.accepted)
            time.sleep(0.05)
        raise AssertionError(f"{len(self.accepted)} deliveries accepted, not {count}: {self.accepted}")

    def _handler(self) -> type[BaseHTTPRequestHandler]:
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                with receiver._lock:
                    receiver.attempts.append(self.headers.get("X-SEGB-Delivery", ""))
                    if not verified(receiver.secret, body, self.headers.get(HEADER, "")):
                        receiver.bad_signatures += 1
                        status = 401
                    elif receiver.refusals_left:
                        receiver.refusals_left -= 1
                        status = 500
                    else:
                        receiver.accepted.append({**json.loads(body), "event_header": self.headers["X-SEGB-Event"]})
                        status = 204
                self.send_response(status)
                self.end_headers()

            def log_message(self, format: str, *args: object) -> None:  # quiet
                pass

        return Handler
