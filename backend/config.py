"""Settings for the SEGB server: one typed class, read from the environment (and `.env`) once."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

PROJECT_ROOT = Path(__file__).resolve().parent.parent
StoreKind = Literal["oxigraph", "memory", "virtuoso", "sparql"]

MIN_SECRET_LENGTH = 32


class Settings(BaseSettings):
    """Every setting has a default and a description; `tests/test_config.py` checks the README documents each."""

    model_config = SettingsConfigDict(env_file=".env", env_file_encoding="utf-8", extra="ignore", populate_by_name=True)

    # --- store -------------------------------------------------------------------------------------------
    store: StoreKind = Field(
        "oxigraph",
        description="Triple store: oxigraph (embedded, on disk), memory (embedded, lost on exit), "
        "virtuoso, or sparql (any SPARQL 1.1 Protocol + Graph Store endpoint).",
    )
    data_dir: Path = Field(Path("data"), description="Directory of the embedded store and the server's files.")
    graph_uri: str = Field(
        "http://amor-segb/events",
        validation_alias="VIRTUOSO_GRAPH_URI",
        description="Named graph that holds the robots' logs (VIRTUOSO_GRAPH_URI, as in the reference).",
    )
    virtuoso_endpoint: str = Field(
        "http://localhost:8890/sparql-auth",
        description="Virtuoso SPARQL endpoint with digest auth (read and update).",
    )
    virtuoso_user: str = Field("dba", description="Virtuoso account used by the server.")
    virtuoso_password: str = Field("", description="Password of VIRTUOSO_USER.")
    sparql_query_endpoint: str = Field("", description="Generic store: SPARQL 1.1 query endpoint URL.")
    sparql_update_endpoint: str = Field("", description="Generic store: SPARQL 1.1 update endpoint URL.")
    sparql_user: str = Field("", description="Generic store: HTTP basic-auth user (empty = none).")
    sparql_password: str = Field("", description="Generic store: HTTP basic-auth password.")
    store_timeout_seconds: float = Field(30.0, gt=0, description="Timeout of one request to a remote store.")
    ping_timeout_seconds: float = Field(1.0, gt=0, description="Timeout of the readiness ping to the store.")
    skolem_base: str = Field(
        "",
        description="IRI prefix for skolemised blank nodes; empty = <graph authority>/.well-known/genid/.",
    )

    # --- limits ------------------------------------------------------------------------------------------
    max_body_bytes: int = Field(64 * 1024 * 1024, gt=0, description="Largest accepted request body (bytes).")
    max_decompressed_bytes: int = Field(
        256 * 1024 * 1024, gt=0, description="Largest gzip-decompressed request body (bytes)."
    )
    max_triples_per_post: int = Field(2_000_000, gt=0, description="Most triples accepted in one post.")

    # --- HTTP servers ------------------------------------------------------------------------------------
    host: str = Field("127.0.0.1", description="Interface the API and UI listen on.")
    api_port: int = Field(5000, ge=0, le=65535, description="Port of the API.")
    ui_port: int = Field(8080, ge=0, le=65535, description="Port of the web UI.")
    backend_url: str = Field(
        "",
        description="URL the UI uses to reach the API; empty = http://127.0.0.1:<API_PORT>.",
    )
    cors_origins: str = Field("", description="Comma-separated origins allowed by CORS (empty = CORS off).")

    # --- auth --------------------------------------------------------------------------------------------
    secret_key: str = Field("", description="HS256 secret for JWTs; empty = authentication disabled.")
    allow_weak_secret: bool = Field(False, description="Start even when SECRET_KEY is shorter than 32 chars.")

    # --- operations --------------------------------------------------------------------------------------
    log_level: str = Field("INFO", validation_alias="LOGGING_LEVEL", description="Log level (LOGGING_LEVEL).")
    sparql_dir: Path = Field(PROJECT_ROOT / "sparql", description="Directory of the .rq query files.")

    @field_validator("graph_uri", "virtuoso_endpoint")
    @classmethod
    def _absolute_http_iri(cls, value: str) -> str:
        if not value.startswith(("http://", "https://")):
            raise ValueError("must be an absolute http(s) IRI")
        return value

    @field_validator("log_level")
    @classmethod
    def _known_level(cls, value: str) -> str:
        level = value.upper()
        if level not in {"DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"}:
            raise ValueError("must be one of DEBUG, INFO, WARNING, ERROR, CRITICAL")
        return level

    @model_validator(mode="after")
    def _secret_strength(self) -> Settings:
        if self.secret_key and len(self.secret_key) < MIN_SECRET_LENGTH and not self.allow_weak_secret:
            raise ValueError(
                f"SECRET_KEY must be at least {MIN_SECRET_LENGTH} characters "
                "(set ALLOW_WEAK_SECRET=true to accept a weaker one)"
            )
        return self

    @property
    def auth_enabled(self) -> bool:
        return bool(self.secret_key)

    @property
    def effective_backend_url(self) -> str:
        return (self.backend_url or f"http://127.0.0.1:{self.api_port}").rstrip("/")

    @property
    def effective_skolem_base(self) -> str:
        if self.skolem_base:
            return self.skolem_base
        scheme, _, rest = self.graph_uri.partition("://")
        authority = rest.split("/", 1)[0]
        return f"{scheme}://{authority}/.well-known/genid/"

    @property
    def cors_origin_list(self) -> list[str]:
        return [origin.strip() for origin in self.cors_origins.split(",") if origin.strip()]
