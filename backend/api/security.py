"""Who is calling: bearer JWTs (HS256) with roles, or everyone-with-every-role when auth is off."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import jwt

Role = Literal["logger", "auditor", "admin"]
ROLES: tuple[Role, ...] = ("logger", "auditor", "admin")
ANONYMOUS_USER = "anonymous_user"


@dataclass(frozen=True)
class Principal:
    """The authenticated caller. `roles` is every role when authentication is disabled."""

    username: str
    roles: frozenset[str]
    authenticated: bool

    def has_any(self, roles: tuple[str, ...]) -> bool:
        return "admin" in self.roles or bool(self.roles.intersection(roles))


class AuthenticationFailed(Exception):
    """No usable credentials: answered with 401 and `WWW-Authenticate: Bearer`."""


class PermissionDenied(Exception):
    """Valid credentials without a role the route needs: answered with 403."""


ANONYMOUS = Principal(ANONYMOUS_USER, frozenset(ROLES), authenticated=False)


def principal_from_header(authorization: str | None, secret: str) -> Principal:
    """Check `Authorization: Bearer <jwt>` against `secret`; raise AuthenticationFailed naming the problem."""
    if not secret:
        return ANONYMOUS
    scheme, _, token = (authorization or "").partition(" ")
    if scheme.lower() != "bearer" or not token.strip():
        raise AuthenticationFailed("Authorization header is required")
    return decode_token(token.strip(), secret)


def decode_token(token: str, secret: str) -> Principal:
    try:
        # The algorithm list is fixed: a token's own header can never choose `none` or another key type.
        claims = jwt.decode(
            token,
            secret,
            algorithms=["HS256"],
            options={"require": ["username", "roles", "exp"]},
        )
    except jwt.MissingRequiredClaimError as error:
        raise AuthenticationFailed(f"Could not validate credentials. Missing claim: {error.claim}") from None
    except jwt.ExpiredSignatureError:
        raise AuthenticationFailed("Could not validate credentials. Expired Token") from None
    except jwt.InvalidTokenError:
        raise AuthenticationFailed("Could not validate credentials. Invalid Token") from None
    username = claims.get("username")
    if not isinstance(username, str) or not username.strip():
        raise AuthenticationFailed("Could not validate credentials. Invalid Token: username claim is invalid")
    roles = claims.get("roles")
    if not isinstance(roles, list) or not roles or not all(isinstance(role, str) for role in roles):
        raise AuthenticationFailed("Could not validate credentials. Invalid Token: roles claim is invalid")
    if not set(roles) <= set(ROLES):
        raise AuthenticationFailed("Could not validate credentials. Invalid Token: role is not allowed")
    return Principal(username.strip(), frozenset(roles), authenticated=True)


def authorize(principal: Principal, roles: tuple[str, ...]) -> None:
    if not principal.has_any(roles):
        raise PermissionDenied("User does not have permission to perform this action")
