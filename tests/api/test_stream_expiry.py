"""An event stream lasts no longer than the token that opened it: once the token expires the stream says so and
ends, so a reader holding an expired token hears nothing more (a new request with it is refused anyway)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.auth import mint_token
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby, publish_message, robot_logger
from tests.support.settle import settle

SECRET = "a-test-secret-that-is-long-enough-for-hs256"
LIFETIME = 60  # the shortest a token may be minted for
STREAMS = ["/reports/stream", "/graph/stream", "/findings/stream", "/timeline/stream"]
AFTER_EXPIRY = "Said after the reader's token expired"


@pytest.fixture
def secured() -> Iterator[LiveServer]:
    with LiveServer(create_app(make_settings(secret_key=SECRET))) as server:
        yield server


def token(role: str, expires_in_seconds: float) -> str:
    """A token of `role` that expires `expires_in_seconds` from now (one shorter-lived than tokens may be is minted
    as if issued earlier)."""
    lifetime = max(LIFETIME, int(expires_in_seconds))
    issued = time.time() - lifetime + expires_in_seconds
    return mint_token(SECRET, username=f"a-{role}", roles=[role], expires_in=lifetime, now=issued).token


def test_every_stream_ends_when_its_token_expires(secured: LiveServer) -> None:
    writer = token("logger", 600)
    lobby().publish_all(secured.url, token=writer)
    settle(secured.url)
    reader = token("auditor", 4)
    expiry = time.time() + 4
    heard: dict[str, tuple[int, list[str], float]] = {}
    opened = {path: threading.Event() for path in STREAMS}

    def listen(path: str) -> None:
        params = {"robot": robot_logger("ari", "ARI").robot_uri} if path == "/timeline/stream" else {}
        lines: list[str] = []
        with httpx.stream(
            "GET", f"{secured.url}{path}", params=params, headers={"Authorization": f"Bearer {reader}"}, timeout=30
        ) as stream:
            opened[path].set()
            for line in stream.iter_lines():  # to the stream's end (a keep-alive comes every 15 s at the latest)
                lines.append(line)
                if time.time() > expiry + 20:
                    lines.append("<still open>")
                    break
            heard[path] = (stream.status_code, lines, time.time())

    readers = [threading.Thread(target=listen, args=(path,)) for path in STREAMS]
    for thread in readers:
        thread.start()
    assert all(event.wait(timeout=30) for event in opened.values())
    time.sleep(max(0.0, expiry - time.time()) + 1)
    assert secured.get("/reports", headers={"Authorization": f"Bearer {reader}"}).status_code == 401
    publish_message(secured.url, AFTER_EXPIRY, token=writer)
    for thread in readers:
        thread.join(timeout=60)
    for path in STREAMS:
        status, lines, ended = heard[path]
        assert status == 200, path
        assert "<still open>" not in lines, f"{path} stayed open after its token expired"
        assert "event: expired" in lines, f"{path} ended without saying why"
        assert ended - expiry < 5, f"{path} ended {ended - expiry:.1f} s after its token expired"
        assert not any(AFTER_EXPIRY in line for line in lines), path


def test_a_stream_opened_with_auth_off_is_not_cut(live_api: LiveServer) -> None:
    """Without authentication there is no token to expire: the stream stays open while its reader listens."""
    with httpx.stream("GET", f"{live_api.url}/graph/stream", timeout=httpx.Timeout(30, read=3)) as stream:
        assert stream.status_code == 200
        with pytest.raises(httpx.ReadTimeout):
            for line in stream.iter_lines():
                assert line != "event: expired"
