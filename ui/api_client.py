"""The UI's only way to data: the backend API over HTTP, forwarding the user's token."""

from __future__ import annotations

from typing import Any

import httpx


class BackendUnavailable(Exception):
    """The API did not answer (down, unreachable, timing out)."""


class BackendError(Exception):
    """The API answered with an error status; `detail` is its message for people."""

    def __init__(self, status: int, detail: str) -> None:
        super().__init__(f"{status}: {detail}")
        self.status = status
        self.detail = detail


class BackendClient:
    """Thin async client. Holds no credentials of its own: each call carries the caller's token."""

    def __init__(
        self, base_url: str, *, timeout_seconds: float = 30.0, transport: httpx.AsyncBaseTransport | None = None
    ):
        self.base_url = base_url.rstrip("/")
        self._client = httpx.AsyncClient(base_url=self.base_url, timeout=timeout_seconds, transport=transport)

    async def request(
        self,
        method: str,
        path: str,
        *,
        token: str | None = None,
        params: dict[str, Any] | None = None,
        json: Any = None,
        content: bytes | None = None,
        headers: dict[str, str] | None = None,
    ) -> httpx.Response:
        try:
            response = await self._client.request(
                method, path, params=_clean(params), json=json, content=content, headers=_with_token(headers, token)
            )
        except httpx.HTTPError as error:
            raise BackendUnavailable(f"The SEGB API at {self.base_url} does not answer ({error}).") from error
        if response.status_code >= 400:
            raise BackendError(response.status_code, _detail(response))
        return response

    async def open_stream(
        self,
        path: str,
        *,
        token: str | None = None,
        params: dict[str, Any] | None = None,
        headers: dict[str, str] | None = None,
        timeout: httpx.Timeout | None = None,
    ) -> httpx.Response:
        """A GET whose body is still to be read, chunk by chunk (`aiter_bytes`); the caller closes it. Error
        statuses raise before any of the body is passed on."""
        request = self._client.build_request(
            "GET",
            path,
            params=_clean(params),
            headers=_with_token(headers, token),
            timeout=timeout or self._client.timeout,
        )
        try:
            response = await self._client.send(request, stream=True)
        except httpx.HTTPError as error:
            raise BackendUnavailable(f"The SEGB API at {self.base_url} does not answer ({error}).") from error
        if response.status_code >= 400:
            try:
                await response.aread()
            finally:
                await response.aclose()
            raise BackendError(response.status_code, _detail(response))
        return response

    async def get_json(self, path: str, *, token: str | None = None, params: dict[str, Any] | None = None) -> Any:
        return (await self.request("GET", path, token=token, params=params)).json()

    async def post_json(self, path: str, body: Any, *, token: str | None = None) -> Any:
        return (await self.request("POST", path, token=token, json=body)).json()

    async def sparql(self, query: str, fmt: str, *, token: str | None = None) -> httpx.Response:
        """The raw answer of `/sparql` in format `fmt`, headers included (`X-SEGB-Truncated`). Posted, so a
        long query never meets a URL length limit."""
        return await self.request(
            "POST",
            "/sparql",
            token=token,
            params={"format": fmt},
            content=query.encode("utf-8"),
            headers={"Content-Type": "application/sparql-query"},
        )

    async def probe(self, path: str) -> tuple[int, Any]:
        """Status and JSON body of a public probe, without raising on error statuses."""
        try:
            response = await self._client.get(path)
        except httpx.HTTPError as error:
            raise BackendUnavailable(f"The SEGB API at {self.base_url} does not answer ({error}).") from error
        try:
            return response.status_code, response.json()
        except ValueError:
            return response.status_code, None

    async def aclose(self) -> None:
        await self._client.aclose()


def _with_token(headers: dict[str, str] | None, token: str | None) -> dict[str, str]:
    sent = dict(headers or {})
    if token:
        sent["Authorization"] = f"Bearer {token}"
    return sent


def _clean(params: dict[str, Any] | None) -> dict[str, Any]:
    return {key: value for key, value in (params or {}).items() if value not in (None, "")}


def _detail(response: httpx.Response) -> str:
    try:
        body = response.json()
    except ValueError:
        return response.text[:500] or response.reason_phrase
    if isinstance(body, dict):
        detail = body.get("message") if isinstance(body.get("detail"), list) else body.get("detail")
        if detail:
            return str(detail)
    return response.reason_phrase
