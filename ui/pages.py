"""Rendering pages: the shared layout context (navigation, session) and the error page."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi import Request
from fastapi.responses import HTMLResponse
from fastapi.templating import Jinja2Templates

from ui.api_client import BackendClient

TEMPLATES = Jinja2Templates(directory=str(Path(__file__).parent / "templates"))

NAVIGATION = [
    ("Reports", "/reports"),
    ("Graph", "/kg-graph"),
    ("Query", "/query"),
    ("Shared context", "/shared-context"),
    ("Logs", "/logs"),
    ("Health", "/health"),
    ("Session", "/session"),
]
TOKEN_COOKIE = "segb_token"


def backend(request: Request) -> BackendClient:
    return request.app.state.backend


def token(request: Request) -> str | None:
    """The user's API token, kept in an HttpOnly cookie by the session page."""
    return request.cookies.get(TOKEN_COOKIE) or None


def render(
    request: Request, template: str, context: dict[str, Any] | None = None, status_code: int = 200
) -> HTMLResponse:
    page = {"navigation": NAVIGATION, "current_path": request.url.path, **(context or {})}
    return TEMPLATES.TemplateResponse(request, template, page, status_code=status_code)


def error_page(request: Request, status_code: int, title: str, message: str) -> HTMLResponse:
    return render(request, "error.html", {"title": title, "message": message, "status": status_code}, status_code)
