"""Authentication mode and the caller's identity (so a UI can show who it acts as, and with which roles)."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import PrincipalDep, SettingsDep

router = APIRouter(tags=["auth"])


class AuthMode(BaseModel):
    auth_enabled: bool


class WhoAmI(BaseModel):
    username: str = Field(examples=["ari"])
    roles: list[str] = Field(examples=[["logger"]])
    authenticated: bool = Field(description="False when authentication is off (everyone has every role).")
    auth_enabled: bool


@router.get("/auth/mode", summary="Authentication mode", response_model=AuthMode)
async def auth_mode(settings: SettingsDep) -> AuthMode:
    """`auth_enabled` is false when SECRET_KEY is empty: every caller then acts with every role. Public."""
    return AuthMode(auth_enabled=settings.auth_enabled)


@router.get(
    "/auth/whoami",
    summary="The caller's identity",
    response_model=WhoAmI,
    responses={401: {"description": "Missing, invalid or expired token"}},
)
async def whoami(principal: PrincipalDep, settings: SettingsDep) -> WhoAmI:
    """Who the bearer token says the caller is. Any valid token; no role needed."""
    return WhoAmI(
        username=principal.username,
        roles=sorted(principal.roles),
        authenticated=principal.authenticated,
        auth_enabled=settings.auth_enabled,
    )
