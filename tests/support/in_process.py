"""Apps served in this process, without a socket: Starlette's `TestClient` runs the whole ASGI app (middleware,
lifespan, routes, the write path's threads) on an event loop of its own, and answers like an `httpx.Client`.

`InProcess(app)` serves one app; `UiOverApi(api_app, settings)` serves the UI with its API client calling the API app
in the same loop (what `segb serve` runs as two servers). Tests that need a real socket (a subprocess client, a
browser, a read timeout on a stream) use `tests.support.live_server.LiveServer` instead.
"""

from __future__ import annotations

from typing import Any

import httpx
from fastapi import FastAPI
from semantic_log_generator import SEGBPublisher
from starlette.testclient import TestClient
from starlette.types import ASGIApp, Receive, Scope, Send

from segb_server.backend.config import Settings
from segb_server.ui.app import create_ui_app

# Requests come from the loopback address, as those of a real local client do (the request log records it).
CLIENT = ("127.0.0.1", 50000)


class InProcess:
    """`with InProcess(app) as served:` — `served.client` (an httpx.Client) reaches the app until the block ends.
    Like a real server: an app's own errors are 500 answers, not exceptions, and redirects are not followed."""

    def __init__(self, app: ASGIApp) -> None:
        self.client = TestClient(app, raise_server_exceptions=False, follow_redirects=False, client=CLIENT)

    def __enter__(self) -> InProcess:
        self.client.__enter__()
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.client.__exit__(*exc_info)

    def get(self, path: str, **options: Any) -> httpx.Response:
        return self.client.get(path, **options)

    def post(self, path: str, **options: Any) -> httpx.Response:
        return self.client.post(path, **options)


API_URL = "http://api.testserver"  # where the UI served with its API (`UiOverApi`) finds the API


class UiOverApi(InProcess):
    """The UI app and the API app it reads, served together in one event loop: `served.client` reaches the UI,
    `served.api` the API (as `segb serve` runs them, without the two sockets). The UI's API client calls the
    API app directly."""

    def __init__(self, api: FastAPI, settings: Settings) -> None:
        transport = httpx.ASGITransport(app=api, raise_app_exceptions=False, client=CLIENT)
        ui = create_ui_app(settings.model_copy(update={"backend_url": API_URL}), backend_transport=transport)
        super().__init__(_Together(ui, api))
        self.api = httpx.Client(base_url=API_URL, transport=_Through(self.client))


class _Together:
    """An ASGI app: requests to the API's host go to the API app, the others to the UI; the lifespan is both
    apps' (the API's started first, stopped last)."""

    def __init__(self, ui: FastAPI, api: FastAPI) -> None:
        self.ui = ui
        self.api = api
        self.api_host = httpx.URL(API_URL).host

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            await self._lifespan(receive, send)
            return
        headers = dict(scope.get("headers") or [])
        host = headers.get(b"host", b"").decode().partition(":")[0]
        await (self.api if host == self.api_host else self.ui)(scope, receive, send)

    async def _lifespan(self, receive: Receive, send: Send) -> None:
        await receive()  # lifespan.startup
        try:
            async with self.api.router.lifespan_context(self.api), self.ui.router.lifespan_context(self.ui):
                await send({"type": "lifespan.startup.complete"})
                await receive()  # lifespan.shutdown
        except Exception as error:
            await send({"type": "lifespan.startup.failed", "message": repr(error)})
            raise
        await send({"type": "lifespan.shutdown.complete"})


class _Through(httpx.BaseTransport):
    """Requests sent through another client (the in-process app's), absolute URLs kept."""

    def __init__(self, client: httpx.Client) -> None:
        self._client = client

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        return self._client.send(request)


class ClientPublisher(SEGBPublisher):
    """The robot client's publisher, posting through an `httpx.Client` (an in-process app's) instead of `requests`:
    the payload, the user and the error handling stay the client's own."""

    def __init__(self, client: httpx.Client, *, token: str | None = None, default_user: str | None = None) -> None:
        super().__init__(base_url=str(client.base_url), token=token, default_user=default_user)
        self._http = client

    def _post_payload(self, payload: dict[str, Any]) -> dict[str, Any]:
        return self._post_json_endpoint(self.endpoint, payload)

    def _post_json_endpoint(self, endpoint: str, payload: dict[str, Any]) -> dict[str, Any]:
        response = self._http.post(endpoint, json=payload, headers=self._headers())
        if response.status_code >= 400:
            raise RuntimeError(f"SEGB API responded with HTTP {response.status_code}: {response.text}")
        return response.json() if response.content else {"status_code": response.status_code}


Server = str | httpx.Client  # a live server's base URL, or a client of an app served in process


def publisher_for(server: Server, user: str | None = None, token: str | None = None) -> SEGBPublisher:
    """The robot client's publisher for `server`."""
    if isinstance(server, str):
        return SEGBPublisher(base_url=server, token=token, default_user=user)
    return ClientPublisher(server, token=token, default_user=user)


def http(server: Server, method: str, path: str, **options: Any) -> httpx.Response:
    """One request to `server` (`path` from its root)."""
    if isinstance(server, httpx.Client):
        options.pop("timeout", None)  # an in-process app has no socket to time out on; a live one's client has one
        return server.request(method, path, **options)
    return httpx.request(method, f"{server}{path}", **{"timeout": 60, **options})
