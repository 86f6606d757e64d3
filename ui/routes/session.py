"""Session page: paste an API token (kept in an HttpOnly cookie and forwarded to the API), see what it grants,
or sign out. Saving goes back to the page that asked for a token."""

from __future__ import annotations

from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from segb_server.ui.api_client import BackendError
from segb_server.ui.csrf import check_csrf
from segb_server.ui.forms import read_form
from segb_server.ui.pages import backend, render
from segb_server.ui.session import TOKEN_COOKIE

router = APIRouter()

NOTICES = {"saved": "Token saved for this browser session.", "signed-out": "Signed out: the token was removed."}


def local_path(value: str | None) -> str | None:
    """`value` when it is a path on this site (`/reports?robot=…`), else None: a sign-in form must never
    send the browser elsewhere (`//evil.example`, `https://…`, `/\\evil`)."""
    if not value or not value.startswith("/") or value.startswith(("//", "/\\")) or "\n" in value or "\r" in value:
        return None
    return value


@router.get("/session", response_class=HTMLResponse)
async def session_page(request: Request, notice: str | None = None, next: str | None = None) -> HTMLResponse:
    return render(request, "session.html", {"notice": NOTICES.get(notice or ""), "next": local_path(next)})


@router.post("/session", response_class=HTMLResponse)
async def save_token(request: Request) -> Response:
    form = await read_form(request)
    check_csrf(request, form)
    back = local_path(form.get("next"))
    pasted = form.get("token", "").strip().removeprefix("Bearer ").strip()
    if not pasted:
        return render(request, "session.html", {"problem": "Paste a token first.", "next": back}, status_code=400)
    try:
        await backend(request).get_json("/auth/whoami", token=pasted)
    except BackendError as error:
        problem = f"The API refused this token: {error.detail}"
        return render(request, "session.html", {"problem": problem, "next": back}, status_code=400)
    response = RedirectResponse(back or "/session?" + urlencode({"notice": "saved"}), status_code=303)
    response.set_cookie(
        TOKEN_COOKIE, pasted, httponly=True, samesite="strict", secure=request.url.scheme == "https", path="/"
    )
    return response


@router.post("/session/logout")
async def sign_out(request: Request) -> Response:
    form = await read_form(request)
    check_csrf(request, form)
    request.app.state.viewers.forget(request.cookies.get(TOKEN_COOKIE))
    response = RedirectResponse("/session?notice=signed-out", status_code=303)
    response.delete_cookie(TOKEN_COOKIE, path="/")
    return response
