"""Minting API tokens (HS256 JWTs) with the claims the server checks."""

from __future__ import annotations

import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass

import jwt

from segb_server.backend.api.security import ROLES
from segb_server.backend.config import MIN_SECRET_LENGTH

MIN_LIFETIME_SECONDS = 60
MAX_LIFETIME_SECONDS = 30 * 24 * 3600


class TokenRequestError(ValueError):
    """The token asked for breaks a rule (unknown role, lifetime out of range, weak secret)."""


@dataclass(frozen=True)
class MintedToken:
    token: str
    username: str
    roles: list[str]
    expires_at: int


def mint_token(
    secret: str,
    *,
    username: str,
    roles: Sequence[str],
    expires_in: int = 3600,
    name: str | None = None,
    allow_weak_secret: bool = False,
    now: float | None = None,
) -> MintedToken:
    """A signed token for `username` with `roles` (deduplicated, order kept), valid for `expires_in` s."""
    if len(secret) < MIN_SECRET_LENGTH and not allow_weak_secret:
        raise TokenRequestError(f"the secret must be at least {MIN_SECRET_LENGTH} characters")
    if not username.strip():
        raise TokenRequestError("the username must not be blank")
    wanted = list(dict.fromkeys(roles))
    unknown = [role for role in wanted if role not in ROLES]
    if not wanted or unknown:
        raise TokenRequestError(f"roles must be among {', '.join(ROLES)} (got {', '.join(unknown) or 'none'})")
    if not MIN_LIFETIME_SECONDS <= expires_in <= MAX_LIFETIME_SECONDS:
        raise TokenRequestError(f"expires-in must be {MIN_LIFETIME_SECONDS}…{MAX_LIFETIME_SECONDS} seconds")
    issued = int(now if now is not None else time.time())
    claims: dict[str, object] = {
        "username": username.strip(),
        "roles": wanted,
        "iat": issued,
        "nbf": issued,
        "exp": issued + expires_in,
        "jti": uuid.uuid4().hex,
    }
    if name:
        claims["name"] = name
    return MintedToken(jwt.encode(claims, secret, algorithm="HS256"), username.strip(), wanted, issued + expires_in)
