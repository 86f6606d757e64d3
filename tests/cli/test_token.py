"""`segb token`: secrets never on the command line, claims the server checks, clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import jwt
import pytest

from segb_server.backend.api.app import create_app
from tests.cli.test_cli import segb
from tests.conftest import make_settings
from tests.support.live_server import LiveServer

pytestmark = pytest.mark.processes  # runs the segb command

SECRET = "s" * 40


def test_token_from_the_environment_is_accepted_by_the_api(memory_store) -> None:  # type: ignore[no-untyped-def]
    made = segb("token", "--username", "ari", "--role", "logger", env={"SECRET_KEY": SECRET})
    assert made.returncode == 0, made.stderr
    token = made.stdout.strip()
    with LiveServer(create_app(make_settings(secret_key=SECRET), store=memory_store)) as server:
        answer = httpx.get(f"{server.url}/auth/whoami", headers={"Authorization": f"Bearer {token}"})
    identity = answer.json()
    assert {key: identity[key] for key in ("username", "roles", "granted_roles", "scopes", "authenticated")} == {
        "username": "ari",
        "roles": ["logger"],
        "granted_roles": ["logger"],
        "scopes": [],
        "authenticated": True,
    }
    assert identity["expires_at"] > 0


def test_claims_roles_deduplicated_and_json_output(tmp_path: Path) -> None:
    secret_file = tmp_path / "secret"
    secret_file.write_text(SECRET + "\n")
    made = segb(
        "token",
        "--username",
        "maria",
        "--role",
        "auditor",
        "--role",
        "admin",
        "--role",
        "auditor",
        "--expires-in",
        "120",
        "--name",
        "Maria",
        "--secret-file",
        str(secret_file),
        "--json",
        env={"SECRET_KEY": "another-secret-that-is-long-enough-0123456789"},
    )
    assert made.returncode == 0, made.stderr
    output = json.loads(made.stdout)
    claims = jwt.decode(output["token"], SECRET, algorithms=["HS256"])  # the file beats the environment
    assert claims["roles"] == ["auditor", "admin"]
    assert claims["exp"] - claims["iat"] == 120
    assert claims["nbf"] == claims["iat"] and len(claims["jti"]) == 32 and claims["name"] == "Maria"
    assert output["roles"] == ["auditor", "admin"] and output["algorithm"] == "HS256"


def test_input_errors_exit_with_code_2_and_say_why(tmp_path: Path) -> None:
    no_secret = segb("token", "--username", "a", "--role", "admin")
    weak = segb("token", "--username", "a", "--role", "admin", env={"SECRET_KEY": "short"})
    too_long = segb(
        "token", "--username", "a", "--role", "admin", "--expires-in", "99999999", env={"SECRET_KEY": SECRET}
    )
    bad_role = segb("token", "--username", "a", "--role", "root", env={"SECRET_KEY": SECRET})
    assert (no_secret.returncode, "no secret" in no_secret.stderr) == (2, True)
    assert (weak.returncode, "at least 32 characters" in weak.stderr) == (2, True)
    assert (too_long.returncode, "expires-in must be" in too_long.stderr) == (2, True)
    assert bad_role.returncode == 2 and "invalid choice: 'root'" in bad_role.stderr
    allowed = segb("token", "--username", "a", "--role", "admin", "--allow-weak-secret", env={"SECRET_KEY": "short"})
    assert allowed.returncode == 0
