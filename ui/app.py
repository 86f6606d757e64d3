"""Building the UI application: pages, static files, security headers, a client for the API."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

import httpx
from fastapi import FastAPI, Request
from fastapi.responses import Response
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from segb_server.backend.config import Settings
from segb_server.ui.api_client import BackendClient, BackendError, BackendUnavailable
from segb_server.ui.badges import BadgeCache, BadgeMiddleware
from segb_server.ui.csrf import CsrfCookieMiddleware, CsrfRejected
from segb_server.ui.forms import BadForm
from segb_server.ui.pages import error_page
from segb_server.ui.query_params import BadFilter
from segb_server.ui.routes import (
    clear,
    export,
    findings,
    graph,
    health,
    home,
    insert,
    ledger,
    live,
    logs,
    people,
    query,
    reports,
    session,
    shared_context,
    timeline,
)
from segb_server.ui.security import SecurityHeaders
from segb_server.ui.session import ViewerCache, ViewerMiddleware

logger = logging.getLogger("segb.ui")

ROUTERS = [
    home.router,
    health.router,
    reports.router,
    timeline.router,
    findings.router,
    graph.router,
    session.router,
    ledger.router,
    shared_context.router,
    query.router,
    insert.router,
    clear.router,
    export.router,
    live.router,
    logs.router,
    people.router,
]


def create_ui_app(
    settings: Settings | None = None, *, backend_transport: httpx.AsyncBaseTransport | None = None
) -> FastAPI:
    """The UI app. It reaches the API over HTTP at BACKEND_URL, or through `backend_transport` when given (tests
    serve the API app to it in the same process)."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.backend = BackendClient(settings.effective_backend_url, transport=backend_transport)
        app.state.viewers = ViewerCache()
        app.state.badges = BadgeCache()
        try:
            yield
        finally:
            await app.state.backend.aclose()

    app = FastAPI(title="SEGB UI", lifespan=lifespan, docs_url=None, redoc_url=None, openapi_url=None)
    app.add_middleware(CsrfCookieMiddleware)
    app.add_middleware(BadgeMiddleware)  # inside the viewer's: it reads what the viewer may see
    app.add_middleware(ViewerMiddleware)
    app.add_middleware(SecurityHeaders)
    app.mount("/static", StaticFiles(directory=Path(__file__).parent / "static"), name="static")
    for router in ROUTERS:
        app.include_router(router)
    _install_error_pages(app)
    return app


def _install_error_pages(app: FastAPI) -> None:
    async def backend_down(request: Request, error: Exception) -> Response:
        return error_page(request, 503, "The SEGB API is unavailable", str(error))

    async def backend_refused(request: Request, error: Exception) -> Response:
        assert isinstance(error, BackendError)
        titles = {401: "Sign-in needed", 403: "Not allowed", 404: "Not found"}
        status = error.status if error.status in (400, 401, 403, 404, 406, 413, 415, 422) else 502
        return error_page(request, status, titles.get(error.status, "The SEGB API refused the request"), error.detail)

    async def http_error(request: Request, error: Exception) -> Response:
        assert isinstance(error, StarletteHTTPException)
        title = "Page not found" if error.status_code == 404 else "Request failed"
        return error_page(request, error.status_code, title, str(error.detail))

    async def bad_filter(request: Request, error: Exception) -> Response:
        return error_page(request, 422, "A filter is not understood", str(error))

    async def refused_form(request: Request, error: Exception) -> Response:
        status = 403 if isinstance(error, CsrfRejected) else 400
        return error_page(request, status, "Form refused", str(error), form_refused=True)

    async def unexpected(request: Request, error: Exception) -> Response:
        logger.exception("unhandled error on %s %s", request.method, request.url.path)
        return error_page(request, 500, "Something went wrong", "The page failed; the server log has the details.")

    app.add_exception_handler(Exception, unexpected)
    app.add_exception_handler(CsrfRejected, refused_form)
    app.add_exception_handler(BadForm, refused_form)
    app.add_exception_handler(BadFilter, bad_filter)
    app.add_exception_handler(BackendUnavailable, backend_down)
    app.add_exception_handler(BackendError, backend_refused)
    app.add_exception_handler(StarletteHTTPException, http_error)
