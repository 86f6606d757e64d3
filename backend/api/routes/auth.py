"""Authentication mode and the caller's identity (so a UI can show who it acts as, and with which roles)."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import PrincipalDep, SettingsDep
from segb_server.backend.auth import ROLES

router = APIRouter(tags=["auth"])


class AuthMode(BaseModel):
    auth_enabled: bool
    roles: list[str] = Field(description="Every role; with authentication off, every caller holds them all.")


class WhoAmI(BaseModel):
    username: str = Field(examples=["ari"])
    roles: list[str] = Field(examples=[["logger"]])
    granted_roles: list[str] = Field(description="The roles the caller acts with: its roles and what they imply.")
    scopes: list[str] = Field(description="IRI prefixes the caller's posts may describe; empty = any.")
    authenticated: bool = Field(description="False when authentication is off (everyone has every role).")
    auth_enabled: bool
    expires_at: int | None = Field(None, description="When the token expires (Unix seconds); null without one.")


@router.get("/auth/mode", summary="Authentication mode", response_model=AuthMode)
async def auth_mode(settings: SettingsDep) -> AuthMode:
    """`auth_enabled` is false when SECRET_KEY is empty: every caller then acts with every role. Public."""
    return AuthMode(auth_enabled=settings.auth_enabled, roles=list(ROLES))


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
        granted_roles=sorted(principal.granted),
        scopes=list(principal.scopes),
        authenticated=principal.authenticated,
        auth_enabled=settings.auth_enabled,
        expires_at=principal.expires_at,
    )
