"""Who is looking at the UI: the token in the session cookie, checked by the API, cached briefly."""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass

from starlette.middleware.base import BaseHTTPMiddleware, RequestResponseEndpoint
from starlette.requests import Request
from starlette.responses import Response

from segb_server.ui.api_client import BackendClient, BackendError, BackendUnavailable
from segb_server.ui.vocabulary import ensure as ensure_vocabulary

TOKEN_COOKIE = "segb_token"
CACHE_SECONDS = 15.0
CACHE_ENTRIES = 1024


@dataclass(frozen=True)
class Viewer:
    """The person using the UI. `status`: auth-off, no-token, active, invalid (expired or bad), unknown."""

    status: str
    username: str | None = None
    roles: frozenset[str] = frozenset()  # the roles the viewer acts with, as the API grants them
    problem: str | None = None
    token_roles: tuple[str, ...] = ()  # the roles the token names
    scopes: tuple[str, ...] = ()
    expires_at: int | None = None

    def can(self, roles: tuple[str, ...] | None) -> bool:
        """Whether pages needing one of `roles` are of use (None = public)."""
        if not roles or self.status in ("auth-off", "unknown"):
            return True
        return not self.roles.isdisjoint(roles)


class ViewerCache:
    """Asking the API on every page would double its load; a token's answer is kept for a few seconds."""

    def __init__(self) -> None:
        self._entries: dict[str, tuple[float, Viewer]] = {}

    async def viewer(self, client: BackendClient, token: str | None) -> Viewer:
        key = hashlib.sha256((token or "").encode()).hexdigest()
        cached = self._entries.get(key)
        if cached and cached[0] > time.monotonic():
            return cached[1]
        viewer = await _ask(client, token)
        if viewer.status != "unknown":
            if len(self._entries) >= CACHE_ENTRIES:
                self._entries.clear()
            self._entries[key] = (time.monotonic() + CACHE_SECONDS, viewer)
        return viewer

    def forget(self, token: str | None) -> None:
        self._entries.pop(hashlib.sha256((token or "").encode()).hexdigest(), None)


async def _ask(client: BackendClient, token: str | None) -> Viewer:
    try:
        mode = await client.get_json("/auth/mode")
        if not mode.get("auth_enabled"):
            return Viewer("auth-off", "anonymous_user", frozenset(mode["roles"]))
        if not token:
            return Viewer("no-token")
        identity = await client.get_json("/auth/whoami", token=token)
    except BackendError as error:
        if error.status == 401:
            return Viewer("invalid", problem=error.detail)
        return Viewer("unknown", problem=error.detail)
    except BackendUnavailable as error:
        return Viewer("unknown", problem=str(error))
    return Viewer(
        "active",
        identity["username"],
        frozenset(identity["granted_roles"]),
        token_roles=tuple(identity["roles"]),
        scopes=tuple(identity["scopes"]),
        expires_at=identity.get("expires_at"),
    )


class ViewerMiddleware(BaseHTTPMiddleware):
    """Puts `request.state.viewer` on every page request (static files are skipped)."""

    async def dispatch(self, request: Request, call_next: RequestResponseEndpoint) -> Response:
        if not request.url.path.startswith("/static/"):
            cache: ViewerCache = request.app.state.viewers
            token = request.cookies.get(TOKEN_COOKIE) or None
            await ensure_vocabulary(request.app.state.backend)
            request.state.viewer = await cache.viewer(request.app.state.backend, token)
        return await call_next(request)
