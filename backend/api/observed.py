"""Counting what the API answers, from outside the routes: posts (outcome, reason, triples, time) and evidence
bundles served. Pure ASGI: only a post's small JSON answer is read back, nothing else is buffered."""

from __future__ import annotations

import json
import time

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from segb_server.backend.services.observability.metrics import EVIDENCE_BUNDLES, record_post

POSTS = ("POST", "/ttl")
BUNDLES = ("GET", "/evidence")
MAX_ANSWER_BYTES = 64 * 1024  # a post's answer is a few hundred bytes: anything longer is not read


class ObservedRequests:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        route = (scope.get("method"), scope.get("path")) if scope["type"] == "http" else None
        if route not in (POSTS, BUNDLES):
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        status = 500
        answer = bytearray()

        async def observe(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            elif message["type"] == "http.response.body" and len(answer) < MAX_ANSWER_BYTES:
                answer.extend(message.get("body", b""))
            await send(message)

        try:
            await self.app(scope, receive, observe)
        finally:
            if route == POSTS:
                body = _json(bytes(answer))
                record_post(status, _reason(status, body), time.perf_counter() - started, _triples(status, body))
            elif status == 200:
                EVIDENCE_BUNDLES.inc()


def _json(answer: bytes) -> dict[str, object]:
    try:
        decoded = json.loads(answer)
    except ValueError:
        return {}
    return decoded if isinstance(decoded, dict) else {}


def _reason(status: int, body: dict[str, object]) -> str | None:
    """A refusal's error code (the API's one error shape names it): a small, fixed set of labels."""
    code = body.get("error")
    return code if status >= 400 and isinstance(code, str) and code.isidentifier() else None


def _triples(status: int, body: dict[str, object]) -> dict[str, int]:
    if status >= 400:
        return {}
    numbers = {name: body.get(name) for name in ("triples_received", "triples_new", "triples_withheld")}
    if not all(isinstance(number, int) for number in numbers.values()):
        return {}
    received, new, withheld = (int(number) for number in numbers.values())  # type: ignore[call-overload]
    return {"new": new, "withheld": withheld, "known": max(received - new - withheld, 0)}
