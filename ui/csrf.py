"""CSRF protection for the UI's state-changing forms (double-submit token).

Each browser gets a random token in a SameSite=Strict, HttpOnly cookie; every form that changes state
carries the same value in a hidden `csrf_token` field, and the POST is refused unless both match. A form
posted from another site carries neither the cookie (SameSite) nor the value (it cannot read it).
"""

from __future__ import annotations

import hmac
import secrets

from starlette.middleware.base import BaseHTTPMiddleware, RequestResponseEndpoint
from starlette.requests import Request
from starlette.responses import Response

CSRF_COOKIE = "segb_csrf"
CSRF_FIELD = "csrf_token"


class CsrfRejected(Exception):
    """A state-changing form arrived without the matching CSRF token."""


def csrf_token(request: Request) -> str:
    """The value to put in a form's hidden `csrf_token` field."""
    existing = request.cookies.get(CSRF_COOKIE)
    if existing:
        return existing
    if not hasattr(request.state, "new_csrf"):
        request.state.new_csrf = secrets.token_urlsafe(32)
    return request.state.new_csrf


def check_csrf(request: Request, form: dict[str, str]) -> None:
    cookie = request.cookies.get(CSRF_COOKIE, "")
    sent = form.get(CSRF_FIELD, "")
    if not cookie or not hmac.compare_digest(cookie, sent):
        raise CsrfRejected("The form's security token is missing or stale. Reload the page and try again.")


class CsrfCookieMiddleware(BaseHTTPMiddleware):
    """Sets the cookie when a page handed out a fresh token."""

    async def dispatch(self, request: Request, call_next: RequestResponseEndpoint) -> Response:
        response = await call_next(request)
        fresh = getattr(request.state, "new_csrf", None)
        if fresh:
            response.set_cookie(
                CSRF_COOKIE, fresh, httponly=True, samesite="strict", secure=request.url.scheme == "https", path="/"
            )
        return response
