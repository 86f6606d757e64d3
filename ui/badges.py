"""The findings badge of the navigation: how many violations the audit rules find now, for viewers who audit.

Asked of the API (`GET /rules`) at most once every few seconds per token, like the viewer itself: a page
shows a count at most that old, and the findings page itself is live."""

from __future__ import annotations

import hashlib
import time

from fastapi import Request
from starlette.middleware.base import BaseHTTPMiddleware, RequestResponseEndpoint
from starlette.responses import Response

from segb_server.ui.api_client import BackendClient, BackendError, BackendUnavailable
from segb_server.ui.session import TOKEN_COOKIE, Viewer

CACHE_SECONDS = 3.0
CACHE_ENTRIES = 256
SKIPPED = ("/static/", "/live/")  # scripts' and streams' requests show no navigation


class BadgeCache:
    def __init__(self) -> None:
        self._entries: dict[str, tuple[float, int | None]] = {}

    async def violations(self, client: BackendClient, token: str | None) -> int | None:
        key = hashlib.sha256((token or "").encode()).hexdigest()
        cached = self._entries.get(key)
        if cached and cached[0] > time.monotonic():
            return cached[1]
        try:
            listing = await client.get_json("/rules", token=token)
            count: int | None = int(listing["counts"]["violation"])
        except (BackendError, BackendUnavailable, KeyError, TypeError, ValueError):
            count = None  # no badge rather than a wrong one
        if len(self._entries) >= CACHE_ENTRIES:
            self._entries.clear()
        self._entries[key] = (time.monotonic() + CACHE_SECONDS, count)
        return count


class BadgeMiddleware(BaseHTTPMiddleware):
    """Puts `request.state.badges` ({navigation path: count}) on page requests of viewers who audit."""

    async def dispatch(self, request: Request, call_next: RequestResponseEndpoint) -> Response:
        viewer: Viewer | None = getattr(request.state, "viewer", None)
        if not request.url.path.startswith(SKIPPED) and viewer is not None and viewer.can(("auditor",)):
            cache: BadgeCache = request.app.state.badges
            count = await cache.violations(request.app.state.backend, request.cookies.get(TOKEN_COOKIE) or None)
            request.state.badges = {"/findings": count} if count else {}
        return await call_next(request)
