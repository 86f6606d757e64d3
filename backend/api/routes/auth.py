"""Whether the server checks tokens (public, so a UI can tell before asking for one)."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel

from backend.api.deps import SettingsDep

router = APIRouter(tags=["auth"])


class AuthMode(BaseModel):
    auth_enabled: bool


@router.get("/auth/mode", summary="Authentication mode", response_model=AuthMode)
def auth_mode(settings: SettingsDep) -> AuthMode:
    """`auth_enabled` is false when SECRET_KEY is empty: every caller then acts with every role."""
    return AuthMode(auth_enabled=settings.auth_enabled)
