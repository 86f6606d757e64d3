"""Who may do what: roles, bearer JWTs (HS256) minted and checked, write scopes. Below the API, so the CLI
(`segb token`) and the routes share one definition; the UI learns the same rules over HTTP (/auth/mode,
/auth/whoami).

Roles: `logger` publishes, `auditor` reads, `admin` may do everything. A token may also carry `scopes`: IRI
prefixes its posts may describe (the subjects of their triples); a token without scopes may write about
anything, as before scopes existed.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import jwt

from segb_server.backend.config import MIN_SECRET_LENGTH

Role = Literal["logger", "auditor", "admin"]
ROLES: tuple[Role, ...] = ("logger", "auditor", "admin")
# The roles each role grants: an admin holds every role.
GRANTS: dict[str, frozenset[str]] = {
    "logger": frozenset({"logger"}),
    "auditor": frozenset({"auditor"}),
    "admin": frozenset(ROLES),
}
ANONYMOUS_USER = "anonymous_user"
MIN_LIFETIME_SECONDS = 60
MAX_LIFETIME_SECONDS = 30 * 24 * 3600
LAST_EXPIRY = 253402300799  # 9999-12-31T23:59:59Z, the last second a date can show
SCOPE_SCHEMES = ("http://", "https://", "urn:")


@dataclass(frozen=True)
class Principal:
    """The authenticated caller. `roles` is every role when authentication is disabled; `scopes` is empty
    when the caller may write about any subject."""

    username: str
    roles: frozenset[str]
    authenticated: bool
    scopes: tuple[str, ...] = ()
    expires_at: int | None = None

    @property
    def granted(self) -> frozenset[str]:
        """Every role the caller acts with, the ones its roles imply included."""
        return frozenset().union(*(GRANTS[role] for role in self.roles))

    def has_any(self, roles: tuple[str, ...]) -> bool:
        return not self.granted.isdisjoint(roles)

    def may_describe(self, iri: str) -> bool:
        return not self.scopes or iri.startswith(self.scopes)


class AuthenticationFailed(Exception):
    """No usable credentials: answered with 401 and `WWW-Authenticate: Bearer`."""


class PermissionDenied(Exception):
    """Valid credentials without a role the route needs, or a write outside the token's scopes: 403."""


ANONYMOUS = Principal(ANONYMOUS_USER, frozenset(ROLES), authenticated=False)


def principal_from_header(authorization: str | None, secret: str) -> Principal:
    """Check `Authorization: Bearer <jwt>` against `secret`; raise AuthenticationFailed naming the problem."""
    if not secret:
        return ANONYMOUS
    if not (authorization or "").strip():
        raise AuthenticationFailed("Authorization header is required")
    scheme, _, token = authorization.strip().partition(" ")  # type: ignore[union-attr]
    if scheme.lower() != "bearer" or not token.strip():
        raise AuthenticationFailed("Authorization header must be 'Bearer <token>' (a token from `segb token`)")
    return decode_token(token.strip(), secret)


def decode_token(token: str, secret: str) -> Principal:
    try:
        # The algorithm list is fixed: a token's own header can never choose `none` or another key type.
        claims = jwt.decode(token, secret, algorithms=["HS256"], options={"require": ["username", "roles", "exp"]})
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
    scopes = claims.get("scopes", [])
    if not isinstance(scopes, list) or not all(_valid_scope(scope) for scope in scopes):
        raise AuthenticationFailed("Could not validate credentials. Invalid Token: scopes claim is invalid")
    return Principal(
        username.strip(),
        frozenset(roles),
        authenticated=True,
        scopes=tuple(scopes),
        expires_at=_expiry(claims["exp"]),
    )


def _expiry(exp: object) -> int:
    """The second from which the token counts as expired. `exp` is a NumericDate (RFC 7519: seconds, possibly with
    a fraction); the JWT library has already refused a past one, reading it as `int(exp)`, which also takes a
    string of digits: here only a number is a time, and only one a clock reaches (a stream waits until it)."""
    if isinstance(exp, bool) or not isinstance(exp, int | float) or not 0 < exp <= LAST_EXPIRY:
        raise AuthenticationFailed("Could not validate credentials. Invalid Token: exp claim is not a time")
    return int(exp)


def authorize(principal: Principal, roles: tuple[str, ...]) -> None:
    if not principal.has_any(roles):
        raise PermissionDenied("User does not have permission to perform this action")


def _valid_scope(scope: object) -> bool:
    return isinstance(scope, str) and scope.startswith(SCOPE_SCHEMES) and len(scope) > len("urn:")


# --- minting -------------------------------------------------------------------------------------------


class TokenRequestError(ValueError):
    """The token asked for breaks a rule (unknown role, lifetime out of range, weak secret, bad scope)."""


@dataclass(frozen=True)
class MintedToken:
    token: str
    username: str
    roles: list[str]
    expires_at: int
    scopes: list[str]


def mint_token(
    secret: str,
    *,
    username: str,
    roles: Sequence[str],
    expires_in: int = 3600,
    name: str | None = None,
    scopes: Sequence[str] = (),
    allow_weak_secret: bool = False,
    now: float | None = None,
) -> MintedToken:
    """A signed token for `username` with `roles` (deduplicated, order kept), valid for `expires_in` s,
    limited to writing about `scopes` (IRI prefixes) when any are given."""
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
    bad_scopes = [scope for scope in scopes if not _valid_scope(scope)]
    if bad_scopes:
        raise TokenRequestError(f"a scope is an IRI prefix starting with http://, https:// or urn: ({bad_scopes[0]!r})")
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
    kept_scopes = list(dict.fromkeys(scopes))
    if kept_scopes:
        claims["scopes"] = kept_scopes
    token = jwt.encode(claims, secret, algorithm="HS256")
    return MintedToken(token, username.strip(), wanted, issued + expires_in, kept_scopes)
