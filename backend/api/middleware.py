"""ASGI middleware of the API (pure ASGI, so streamed answers stay streamed): the last-resort 500 and the
security headers every answer carries."""

from __future__ import annotations

import json
import logging

from starlette.types import ASGIApp, Message, Receive, Scope, Send

logger = logging.getLogger("segb.api")

# JSON and files need no scripts or frames of their own; the documentation pages set a policy of their own.
API_CSP = "default-src 'none'; frame-ancestors 'none'; base-uri 'none'"
SECURITY_HEADERS = (
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"x-frame-options", b"DENY"),
)


class UnexpectedErrors:
    """Turns an error no handler knew into a 500 in the one error shape, from inside the CORS and request-id
    middleware (so the answer carries their headers), and closes the connection: a request that failed this
    way may have left it unusable. Nothing of the error reaches the client; the server log has it."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def tracking_send(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive, tracking_send)
        except Exception:
            logger.exception("unhandled error on %s %s", scope.get("method"), scope.get("path"))
            if started:  # the answer is under way (a streamed export): the connection can only be dropped
                raise
            body = json.dumps(
                {"detail": "Internal server error; see the server log.", "error": "internal_error", "status": 500}
            ).encode()
            headers = [(b"content-type", b"application/json"), (b"connection", b"close")]
            await send({"type": "http.response.start", "status": 500, "headers": headers})
            await send({"type": "http.response.body", "body": body})


class SecurityHeaders:
    """Adds the security headers to every answer, and a restrictive CSP to those without one of their own."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                present = {name.lower() for name, _ in headers}
                headers += [(name, value) for name, value in SECURITY_HEADERS if name not in present]
                if b"content-security-policy" not in present:
                    headers.append((b"content-security-policy", API_CSP.encode()))
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, with_headers)


class HeadAsGet:
    """Answers HEAD wherever GET is answered (`curl -I /healthz/ready`, uptime monitors): the request goes to the
    GET route, and only the answer's status and headers are sent. Once they are, the route is told the client
    has gone, so a stream (`/reports/stream`) ends instead of producing a body nobody reads."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "HEAD":
            await self.app(scope, receive, send)
            return
        answered = False

        async def until_answered() -> Message:
            if answered:
                return {"type": "http.disconnect"}
            return await receive()

        async def headers_only(message: Message) -> None:
            nonlocal answered
            if message["type"] == "http.response.start":
                await send(message)
                await send({"type": "http.response.body", "body": b"", "more_body": False})
                answered = True
            # The body's messages are dropped: the answer is complete already.

        await self.app({**scope, "method": "GET"}, until_answered, headers_only)
