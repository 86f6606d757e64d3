"""Settings: each one is documented in the README, and the types and checks hold."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from segb_server.backend.config import Settings
from segb_server.backend.services.views.process import views_home
from tests.conftest import make_settings

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def env_names() -> list[str]:
    names = []
    for name, field in Settings.model_fields.items():
        alias = field.validation_alias
        names.append(alias if isinstance(alias, str) else name.upper())
    return names


@pytest.mark.parametrize("variable", env_names())
def test_every_setting_is_documented_in_the_readme(variable: str) -> None:
    assert f"| `{variable}` |" in README


@pytest.mark.parametrize("variable", env_names())
def test_every_setting_has_a_description(variable: str) -> None:
    field = next(f for n, f in Settings.model_fields.items() if variable in (n.upper(), f.validation_alias))
    assert field.description


def test_environment_names_match_the_reference_deployment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("VIRTUOSO_GRAPH_URI", "http://example.org/g")
    monkeypatch.setenv("LOGGING_LEVEL", "debug")
    settings = Settings(_env_file=None)  # type: ignore[call-arg]
    assert settings.graph_uri == "http://example.org/g"
    assert settings.log_level == "DEBUG"


def test_short_secrets_are_refused_unless_explicitly_allowed() -> None:
    with pytest.raises(ValidationError, match="at least 32 characters"):
        make_settings(secret_key="too-short")
    assert make_settings(secret_key="too-short", allow_weak_secret=True).auth_enabled


def test_skolem_base_defaults_to_the_graph_authority() -> None:
    assert make_settings().effective_skolem_base == "http://amor-segb/.well-known/genid/"


def test_a_retention_past_the_calendar_is_refused_with_its_bound() -> None:
    """Counting back millions of days leaves the calendar: the server would start, then fail every erasure run."""
    with pytest.raises(ValidationError, match="less than or equal to 36525"):
        make_settings(retention_days=3_000_000)
    assert make_settings(retention_days=36_525).retention_days == 36_525


@pytest.mark.parametrize(
    ("store", "views_process", "workers", "home"),
    [
        ("oxigraph", None, False, "child"),  # the embedded store: the views run beside the API process
        ("virtuoso", None, True, "this"),  # a remote store: the leading worker keeps them
        ("sparql", None, False, "this"),
        ("virtuoso", True, True, "sibling"),  # asked for: beside the workers
        ("oxigraph", False, False, "this"),
        ("memory", True, False, "this"),  # nothing another process could read
    ],
)
def test_where_the_views_are_kept_by_default_depends_on_the_store(
    store: str, views_process: bool | None, workers: bool, home: str
) -> None:
    settings = make_settings(store=store, views_process=views_process, virtuoso_password="a-password")
    assert views_home(settings, workers=workers).value == home


def test_posts_wait_for_the_views_sooner_on_the_embedded_store() -> None:
    assert make_settings(store="oxigraph").effective_views_max_lag_seconds == 1.3
    assert make_settings(store="virtuoso", virtuoso_password="a-password").effective_views_max_lag_seconds == 2.0
    assert make_settings(store="sparql", views_max_lag_seconds=0.0).effective_views_max_lag_seconds == 0.0
