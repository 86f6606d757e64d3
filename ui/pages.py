"""Rendering pages: the shared layout context (navigation, session) and the error page."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi import Request
from fastapi.responses import HTMLResponse, JSONResponse, Response
from fastapi.templating import Jinja2Templates
from jinja2 import FileSystemLoader

from segb_server.backend.services.direction_controls import page_environment
from segb_server.ui.api_client import BackendClient, BackendError
from segb_server.ui.csrf import csrf_token
from segb_server.ui.display import FILTERS
from segb_server.ui.query_params import TIME_EXAMPLE, TIME_PATTERN
from segb_server.ui.session import TOKEN_COOKIE, Viewer

# Every page shows a robot's direction controls as marks (direction_controls.py), whatever its template writes.
TEMPLATES = Jinja2Templates(env=page_environment(FileSystemLoader(Path(__file__).parent / "templates")))
TEMPLATES.env.filters.update(FILTERS)
TEMPLATES.env.globals.update(time_pattern=TIME_PATTERN, time_example=TIME_EXAMPLE)  # the time filters' inputs

AUDITOR = ("auditor",)
ADMIN = ("admin",)
# (label, path, roles that can use the page; None = public). Pages a viewer cannot use are not shown.
NAVIGATION: list[tuple[str, str, tuple[str, ...] | None]] = [
    ("Reports", "/reports", AUDITOR),
    ("Timeline", "/timeline", AUDITOR),
    ("Findings", "/findings", AUDITOR),
    ("Graph", "/kg-graph", AUDITOR),
    ("Query", "/query", AUDITOR),
    ("Shared context", "/shared-context", ADMIN),
    ("Ledger", "/ledger", AUDITOR),
    ("Insert a log", "/logs/insert", ADMIN),
    ("Clear the graph", "/logs/delete", ADMIN),
    ("People", "/people", ADMIN),
    ("Logs", "/logs", ADMIN),
    ("Health", "/health", None),
    ("Session", "/session", None),
]


def backend(request: Request) -> BackendClient:
    return request.app.state.backend


def token(request: Request) -> str | None:
    """The user's API token, kept in an HttpOnly cookie by the session page."""
    return request.cookies.get(TOKEN_COOKIE) or None


def viewer(request: Request) -> Viewer:
    return getattr(request.state, "viewer", None) or Viewer("unknown")


def render(
    request: Request, template: str, context: dict[str, Any] | None = None, status_code: int = 200
) -> HTMLResponse:
    who = viewer(request)
    page = {
        "navigation": [(label, path) for label, path, roles in NAVIGATION if who.can(roles)],
        "current_nav": current_nav(request.url.path),
        "badges": getattr(request.state, "badges", {}),
        "viewer": who,
        "csrf_token": csrf_token(request),
        **(context or {}),
    }
    return TEMPLATES.TemplateResponse(request, template, page, status_code=status_code)


def require(request: Request, roles: tuple[str, ...]) -> None:
    """Refuse a page the viewer's roles cannot use, as the API would: before any form is shown."""
    who = viewer(request)
    if who.can(roles):
        return
    if who.status in ("no-token", "invalid"):
        raise BackendError(401, "Sign in with a token first.")
    held = ", ".join(sorted(who.roles)) or "none"
    raise BackendError(403, f"This page needs the {' or '.join(roles)} role; your token has {held}.")


def current_nav(path: str) -> str | None:
    """The navigation entry a page belongs to: the longest one its path starts with (/logs/insert is not
    /logs)."""
    owners = [href for _, href, _ in NAVIGATION if path == href or path.startswith(href + "/")]
    return max(owners, key=len, default=None)


def error_page(request: Request, status_code: int, title: str, message: str, *, form_refused: bool = False) -> Response:
    """An HTML error page, or `{"detail", "title", "status"}` for the page scripts' JSON requests. `form_refused`:
    a 403 for the form itself (its security token), not for the token's roles."""
    if "application/json" in request.headers.get("accept", ""):
        return JSONResponse({"detail": message, "title": title, "status": status_code}, status_code=status_code)
    # Where a sign-in should lead back to: the page that failed, when opening it again is harmless.
    back = None
    if request.method == "GET":
        back = request.url.path + (f"?{request.url.query}" if request.url.query else "")
    context = {"title": title, "message": message, "status": status_code, "back": back, "form_refused": form_refused}
    return render(request, "error.html", context, status_code)
