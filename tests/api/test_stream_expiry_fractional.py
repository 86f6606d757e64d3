"""A token's `exp` is a NumericDate (RFC 7519): seconds, possibly with a fraction. A stream opened with a token whose
`exp` has one ends when that token expires, as a stream opened with a whole-second token does; a token whose `exp`
is no number (a string of digits, which the JWT library would read as one) or no reachable time is refused."""

from __future__ import annotations

import time
from collections.abc import Iterator

import httpx
import jwt
import pytest

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.scenarios import robot_logger

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
STREAMS = ["/reports/stream", "/graph/stream", "/findings/stream", "/timeline/stream"]


@pytest.fixture(scope="module")
def secured() -> Iterator[LiveServer]:
    with LiveServer(create_app(make_settings(secret_key=SECRET))) as server:
        yield server


def auditor_token(exp: object) -> str:
    claims = {"username": "an-auditor", "roles": ["auditor"], "iat": int(time.time()) - 10, "exp": exp}
    return jwt.encode(claims, SECRET, algorithm="HS256")


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


@pytest.mark.parametrize("path", STREAMS)
def test_a_stream_ends_when_a_token_with_a_fractional_exp_expires(secured: LiveServer, path: str) -> None:
    expiry = time.time() + 2.5
    reader = auditor_token(expiry)  # a float, e.g. 1764625321.87
    params = {"robot": robot_logger("ari", "ARI").robot_uri} if path == "/timeline/stream" else {}
    lines: list[str] = []
    with httpx.stream(
        "GET", f"{secured.url}{path}", params=params, headers=bearer(reader), timeout=httpx.Timeout(30, read=20)
    ) as stream:
        assert stream.status_code == 200
        for line in stream.iter_lines():  # to the stream's end (a keep-alive comes every 15 s at the latest)
            lines.append(line)
            if time.time() > expiry + 20:
                break
    ended = time.time()
    assert "event: expired" in lines, f"{path} stayed open after its token expired: {lines}"
    assert ended - expiry < 3, f"{path} ended {ended - expiry:.1f} s after its token expired"


def test_who_a_fractional_exp_token_is_says_when_it_expires_in_whole_seconds(secured: LiveServer) -> None:
    exp = time.time() + 600.75
    answer = secured.get("/auth/whoami", headers=bearer(auditor_token(exp)))
    assert answer.status_code == 200, answer.text
    assert answer.json()["expires_at"] == int(exp)  # where the token check counts it expired


@pytest.mark.parametrize(
    "exp",
    [str(int(time.time()) + 600), f"{time.time() + 600}", True, [int(time.time()) + 600], 10**400, 1e300],
    ids=["digits-string", "decimal-string", "boolean", "list", "huge-integer", "huge-float"],
)
def test_a_token_whose_exp_is_no_reachable_time_is_refused(secured: LiveServer, exp: object) -> None:
    for path in ("/auth/whoami", "/reports/stream"):
        answer = secured.get(path, headers=bearer(auditor_token(exp)))
        assert answer.status_code == 401, (path, answer.text)
        assert answer.json()["detail"].startswith("Could not validate credentials"), answer.text
