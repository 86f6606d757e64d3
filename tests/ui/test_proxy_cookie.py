"""Behind a TLS-terminating proxy the session cookie is Secure, and only a trusted proxy can say so."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest

from segb_server.backend.auth import mint_token
from tests.cli.test_cli import SEGB, clean_env
from tests.support.net import free_port
from tests.support.processes import running

pytestmark = pytest.mark.processes  # runs segb serve behind uvicorn's proxy handling

SECRET = "p" * 40


def serve_ui(trusted: str) -> Iterator[str]:
    api_port, ui_port = free_port(), free_port()
    url = f"http://127.0.0.1:{ui_port}"
    with running(
        [*SEGB, "serve", "--store", "memory", "--api-port", str(api_port), "--ui-port", str(ui_port)],
        ready=f"{url}/health",
        env=clean_env({"FORWARDED_ALLOW_IPS": trusted, "SECRET_KEY": SECRET}),
    ):
        yield url


def saved_cookie(url: str) -> str:
    """Save a token on the session page as a browser behind an HTTPS proxy would; the session cookie's header."""
    proxied = {"X-Forwarded-Proto": "https"}
    page = httpx.get(f"{url}/session", headers=proxied)
    token_field = page.text.split('name="csrf_token" value="', 1)[1].split('"', 1)[0]
    # The browser sends its cookies back over its HTTPS connection to the proxy, Secure ones included.
    csrf_cookie = page.headers["set-cookie"].split(";", 1)[0]
    token = mint_token(SECRET, username="auditor", roles=["auditor"]).token
    answer = httpx.post(
        f"{url}/session", data={"csrf_token": token_field, "token": token}, headers={**proxied, "Cookie": csrf_cookie}
    )
    return next(value for name, value in answer.headers.multi_items() if name == "set-cookie" and "segb_token" in value)


@pytest.fixture
def trusted_proxy() -> Iterator[str]:
    yield from serve_ui("127.0.0.1")


@pytest.fixture
def untrusted_proxy() -> Iterator[str]:
    yield from serve_ui("10.99.99.99")


def test_the_session_cookie_is_secure_behind_a_trusted_tls_proxy(trusted_proxy: str) -> None:
    assert "Secure" in saved_cookie(trusted_proxy)


def test_a_forwarded_proto_from_an_untrusted_address_is_ignored(untrusted_proxy: str) -> None:
    assert "Secure" not in saved_cookie(untrusted_proxy)
