"""Building the API application from settings (and, in tests, an already open store)."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import anyio
from fastapi import FastAPI
from fastapi.middleware.cors import CORSMiddleware

from segb_server.backend import __version__
from segb_server.backend.api.docs import install_docs
from segb_server.backend.api.errors import document_error_shape, install_error_handlers
from segb_server.backend.api.middleware import HeadAsGet, SecurityHeaders, UnexpectedErrors
from segb_server.backend.api.observed import ObservedRequests
from segb_server.backend.api.request_context import RequestContext
from segb_server.backend.api.routes import (
    auth,
    events,
    evidence,
    findings,
    graph,
    health,
    ingest,
    ledger,
    live,
    logs,
    metrics,
    people,
    reports,
    shared_context,
    sparql,
    sparql_examples,
    timeline,
    validate,
    vocabulary,
    webhooks,
)
from segb_server.backend.config import Settings
from segb_server.backend.demo import load_demo
from segb_server.backend.services.container import REQUIRED_QUERIES, build_services
from segb_server.backend.services.observability.watching import Watching
from segb_server.backend.services.ops.server_log import ServerLog
from segb_server.backend.services.ops.store_monitor import StoreMonitor
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.views.channel import StoreChannel
from segb_server.backend.services.views.process import CHANNEL_NICENESS, ViewsHome, ViewsProcess, ViewsStatus
from segb_server.backend.services.writing.write_path import Role
from segb_server.backend.store.base import Store
from segb_server.backend.store.factory import open_store
from segb_server.backend.store.oxigraph import OxigraphStore

logger = logging.getLogger("segb.api")

DESCRIPTION = """
The **SEGB server** (Semantic Ethical Glass Box) receives what social robots log — what they perceive,
decide and say — as RDF, keeps it in a triple store, and serves the audits built on it.

* Robots publish with the PyPI client `semantic-log-generator` (`SEGBPublisher` → `POST /ttl`).
* Authentication: when `SECRET_KEY` is set, send `Authorization: Bearer <JWT>` (HS256) with roles
  `logger` (publish), `auditor` (read), `admin` (everything). `GET /auth/mode` tells which mode is on.
* Errors always have the JSON shape `{"detail", "error", "status"}`.
"""

ROUTERS = [
    health.router,
    metrics.router,
    auth.router,
    ingest.router,
    validate.router,
    events.router,
    evidence.router,
    graph.router,
    findings.router,
    ledger.router,
    sparql.router,
    sparql_examples.router,
    logs.router,
    people.router,
    shared_context.router,
    vocabulary.router,
    webhooks.router,
]


def create_app(
    settings: Settings | None = None,
    store: Store | None = None,
    *,
    demo: bool = False,
    views_home: ViewsHome = ViewsHome.THIS,
) -> FastAPI:
    """The API app. With `store` given, the app uses it and leaves closing it to the caller. With `demo`, the
    demo dataset is loaded into an empty store before the first request is served. `views_home`: which process
    keeps the views (`backend/services/views/process.py`); this one's own thread unless `segb serve` says otherwise."""
    settings = settings or Settings()
    # Loaded here, before the app exists: the report routes and their documentation are made from it.
    catalog = Catalog(settings.sparql_dir, required=REQUIRED_QUERIES)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        server_log = ServerLog.from_settings(settings)
        server_log.install()
        active_store = store if store is not None else open_store(settings)
        role = Role.WHOLE if views_home is ViewsHome.THIS else Role.API
        app.state.services = build_services(settings, active_store, server_log=server_log, catalog=catalog, role=role)
        if role is Role.API:
            app.state.services.writes.views_elsewhere = ViewsStatus(settings.data_dir)
        app.state.watching = watching = Watching(app.state.services)  # metrics, webhooks, traces for their tools
        # The embedded store is read by the views' process through this one (RocksDB lets one process open it).
        channel = (
            StoreChannel(active_store, niceness=CHANNEL_NICENESS)
            if views_home is ViewsHome.CHILD and isinstance(active_store, OxigraphStore)
            else None
        )
        address = channel.address if channel is not None else None
        views = ViewsProcess(settings, address) if views_home is ViewsHome.CHILD else None
        logger.info("SEGB API ready (store=%s, auth=%s)", active_store.kind, settings.auth_enabled)
        monitor = StoreMonitor(
            active_store, max_retry_seconds=settings.store_retry_max_seconds, check_seconds=settings.store_check_seconds
        )
        await anyio.to_thread.run_sync(app.state.services.start)  # reads the store's cursor: I/O
        if views is not None:
            views.start()
        if demo:
            # The app's own services: with STORE=memory the journal and resolver exist nowhere else.
            await anyio.to_thread.run_sync(load_demo, app.state.services)
        try:
            async with anyio.create_task_group() as background:
                background.start_soon(monitor.run)
                yield
                background.cancel_scope.cancel()
        finally:
            if views is not None:  # it reads the store through this process: it stops first
                await anyio.to_thread.run_sync(views.stop)
            watching.close()
            app.state.services.close()
            if channel is not None:
                channel.close()
            if store is None:
                active_store.close()
            server_log.uninstall()

    app = FastAPI(
        title="SEGB server",
        version=__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        license_info={"name": "Apache-2.0"},
        docs_url=None,
        redoc_url=None,
    )
    install_docs(app)
    install_error_handlers(app)
    document_error_shape(app)
    # Added innermost first: a 500 made by UnexpectedErrors still passes CORS (so a browser sees its status),
    # the security headers and the request id.
    app.add_middleware(UnexpectedErrors)
    app.add_middleware(ObservedRequests)  # outside the 500s: they are counted too
    if settings.cors_origin_list:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origin_list,
            allow_credentials=settings.cors_allow_credentials,
            allow_methods=["GET", "POST"],
            allow_headers=["Authorization", "Content-Type", "Content-Encoding", "X-Request-ID"],
            expose_headers=["X-Request-ID", "X-SEGB-Truncated", "X-SEGB-Max-Rows", "Retry-After"],
        )
    app.add_middleware(HeadAsGet)  # inside the request id's: the log says HEAD
    app.add_middleware(SecurityHeaders)
    app.add_middleware(RequestContext)  # outermost: every answer carries the id
    for router in [*ROUTERS, live.router, timeline.router, reports.build_router(catalog)]:
        app.include_router(router)
    return app
