"""FastAPI dependencies: the services, the caller's identity and role checks, size-limited bodies."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Annotated

from fastapi import Depends, Request

from segb_server.backend.auth import Principal, authorize, principal_from_header
from segb_server.backend.config import Settings
from segb_server.backend.services.container import Services
from segb_server.backend.services.errors import PayloadTooLarge

# Dependencies are `async def` on purpose: they do no I/O, and FastAPI would run plain `def` ones in the
# thread pool, costing a thread hop each on every request.


async def get_services(request: Request) -> Services:
    return request.app.state.services


async def get_settings(request: Request) -> Settings:
    return request.app.state.services.settings


ServicesDep = Annotated[Services, Depends(get_services)]
SettingsDep = Annotated[Settings, Depends(get_settings)]


async def get_principal(request: Request, settings: SettingsDep) -> Principal:
    principal = principal_from_header(request.headers.get("authorization"), settings.secret_key)
    request.state.principal = principal
    return principal


PrincipalDep = Annotated[Principal, Depends(get_principal)]


def require(*roles: str) -> Callable[[Principal], Awaitable[Principal]]:
    """Dependency that lets the call through when the caller holds one of `roles` (admin holds all)."""

    async def check(principal: PrincipalDep) -> Principal:
        authorize(principal, roles)
        return principal

    check.__name__ = f"require_{'_or_'.join(roles)}"
    return check


# The logger role is a robot publishing its logs: named `Publisher`, so no route reads as taking a logging.Logger.
Publisher = Annotated[Principal, Depends(require("logger"))]
Auditor = Annotated[Principal, Depends(require("auditor"))]
Admin = Annotated[Principal, Depends(require("admin"))]


async def read_limited_body(request: Request, settings: SettingsDep) -> bytes:
    """The raw body, refused with 413 as soon as it passes MAX_BODY_BYTES (before reading it all)."""
    limit = settings.max_body_bytes
    declared = request.headers.get("content-length")
    if declared and declared.isdigit() and int(declared) > limit:
        raise PayloadTooLarge(f"The request body is over {limit} bytes (MAX_BODY_BYTES).")
    chunks = bytearray()
    async for chunk in request.stream():
        chunks += chunk
        if len(chunks) > limit:
            raise PayloadTooLarge(f"The request body is over {limit} bytes (MAX_BODY_BYTES).")
    return bytes(chunks)


LimitedBody = Annotated[bytes, Depends(read_limited_body)]
