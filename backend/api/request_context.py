"""Request ids and one structured log line per request.

An incoming `X-Request-ID` is kept only when it is short and made of safe characters (it ends up in logs
and headers, so a newline or markup must never pass); otherwise the server mints one. The id is echoed in
the response and logged with the method, path, status, duration, authenticated user and, for a publish,
the triples written; the fields also travel as structured data to the server log (services/server_log.py).
"""

from __future__ import annotations

import logging
import re
import time
import uuid

from starlette.types import ASGIApp, Message, Receive, Scope, Send

logger = logging.getLogger("segb.requests")

HEADER = b"x-request-id"
SAFE_REQUEST_ID = re.compile(r"[A-Za-z0-9._-]{1,64}")


def logged_path(path: str) -> str:
    """The path as the log writes it: a person's IRI in the path (`/humans/{iri}/export`) is left out, so the
    log never names someone an erasure must forget."""
    if path.startswith("/humans/") and path != "/humans/erase":
        return "/humans/{iri}/" + path.rstrip("/").rsplit("/", 1)[-1]
    return path


def request_id_from(headers: list[tuple[bytes, bytes]]) -> str:
    for name, value in headers:
        if name.lower() == HEADER:
            candidate = value.decode("latin-1")
            if SAFE_REQUEST_ID.fullmatch(candidate):
                return candidate
            break
    return uuid.uuid4().hex


class RequestContext:
    """Pure ASGI middleware (no response buffering, so streamed exports stay streamed)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        request_id = request_id_from(scope.get("headers", []))
        scope.setdefault("state", {})["request_id"] = request_id
        started = time.perf_counter()
        status = 500

        async def send_with_id(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                headers = [(k, v) for k, v in message.get("headers", []) if k.lower() != HEADER]
                message = {**message, "headers": [*headers, (HEADER, request_id.encode())]}
            await send(message)

        try:
            await self.app(scope, receive, send_with_id)
        finally:
            principal = scope["state"].get("principal")
            fields = {
                "request_id": request_id,
                "method": scope["method"],
                "path": logged_path(scope["path"]),  # never the query string: it may hold a query or a token
                "status": status,
                "duration_ms": round((time.perf_counter() - started) * 1000, 1),
                "user": getattr(principal, "username", None),
                "origin_ip": (scope.get("client") or (None,))[0],  # XFF counts only from a trusted proxy (uvicorn)
                "triples_written": scope["state"].get("triples_written"),  # set by POST /ttl
                "log_id": scope["state"].get("log_id"),  # set by POST /ttl
            }
            written, log_id = fields["triples_written"], fields["log_id"]
            logger.info(
                "request id=%s method=%s path=%s status=%d ms=%.1f user=%s%s%s",
                request_id,
                fields["method"],
                fields["path"],
                status,
                fields["duration_ms"],
                fields["user"] or "-",
                "" if written is None else f" triples_written={written}",
                "" if log_id is None else f" log_id={log_id}",
                extra=fields,
            )
