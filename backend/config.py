"""Settings for the SEGB server: one typed class, read from the environment (and `.env`) once."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

# The folder holding backend/ and sparql/: the repository's top level, or `segb_server/` once installed (the
# queries are package data there), so the default SPARQL_DIR is right in a checkout and in a wheel.
PACKAGE_ROOT = Path(__file__).resolve().parent.parent
StoreKind = Literal["oxigraph", "memory", "virtuoso", "sparql"]

MIN_SECRET_LENGTH = 32
# The AI Act asks deployers of high-risk AI systems (emotion recognition is one, Annex III) to keep the logs they
# generate automatically for at least six months (Art. 19 and 26(6)).
MIN_RETENTION_DAYS = 183
MAX_RETENTION_DAYS = 36_525  # a century: longer is "forever" (leave RETENTION_DAYS empty), and millions of days
# counted back from now leave the calendar


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
    store_retry_max_seconds: float = Field(
        30.0, gt=0, description="Longest wait between retries while the store does not answer (0.5 s doubling)."
    )
    store_check_seconds: float = Field(
        15.0, gt=0, description="Interval of the background check once the store answers (logs lost/back)."
    )
    ingest_ack: Literal["auto", "journal", "store"] = Field(
        "auto",
        description="When a post is answered: once durable in the journal (journal), or once the store applied "
        "it too (store); auto = store on the embedded store, journal on remote stores.",
    )
    ingest_apply_timeout_seconds: float = Field(
        10.0, gt=0, description="With INGEST_ACK=store, how long a post waits for the store before a 503."
    )
    views_max_lag_seconds: float | None = Field(
        None,
        ge=0,
        description="While the reports are further behind than this (seconds), a post's answer waits for them, so "
        "robots slow down to the pace the views keep (0 = answers never wait); unset: 1.3 on the embedded store "
        "and in memory, 2 on a remote store.",
    )
    views_max_hold_seconds: float = Field(
        10.0, ge=0, description="Longest a post's answer waits for the views (VIEWS_MAX_LAG_SECONDS)."
    )
    journal_max_backlog: int = Field(
        100_000, ge=0, description="Entries the store may fall behind the journal before posts get 503 (0 = no limit)."
    )
    state_url: str = Field(
        "",
        description="Where the journal and shared contexts live: empty = SQLite files in DATA_DIR; "
        "postgresql://user:password@host:port/db = a PostgreSQL database API processes on several hosts share.",
    )
    journal_max_bytes: int = Field(
        0, ge=0, description="Largest size of the journal's database in bytes (0 = no limit)."
    )
    journal_sync: Literal["normal", "full"] = Field(
        "normal",
        description="normal: a journal commit survives a crash of the server; full: also a power cut (slower).",
    )
    apply_batch_triples: int = Field(
        20_000, gt=0, description="Most triples the applier writes to the store in one step."
    )
    keep_views: bool = Field(
        True,
        description="Keep the reports' rows and the graph index current as robots write; false: reports are "
        "evaluated by their queries on every request and /graph answers 503 (to measure what keeping them costs).",
    )
    views_process: bool | None = Field(
        None,
        description="With `segb serve`, keep the views in a process of their own beside the API's, so requests "
        "never wait for the views' work (not with STORE=memory); false: the API process keeps them in a thread. "
        "Unset: on with the embedded store only (on a remote store it slowed the posts, docs/scaling.md).",
    )
    retention_days: int | None = Field(
        None,
        ge=1,
        le=MAX_RETENTION_DAYS,
        description="Days robots' posts are kept; older posts lose their content by an erasure (receipts and "
        "erasure records stay); empty = kept forever. At least 183 (six months) unless ALLOW_SHORT_RETENTION, at "
        "most 36525 (a century).",
    )
    allow_short_retention: bool = Field(
        False, description="Accept RETENTION_DAYS under 183 (when the AI Act's six months do not apply)."
    )
    retention_check_seconds: float = Field(
        3600.0, gt=0, description="How often the server erases posts older than RETENTION_DAYS."
    )
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
    sparql_timeout_seconds: float = Field(
        30.0, gt=0, description="Longest run of one user SPARQL query (/sparql, /query) before a 503 query_timeout."
    )
    sparql_workers: int = Field(
        2, ge=1, description="Worker processes that run user SPARQL on the embedded store (queries at once)."
    )
    sparql_max_memory_bytes: int = Field(
        2 * 1024 * 1024 * 1024,
        ge=64 * 1024 * 1024,
        description="Memory one user SPARQL query may use on the embedded store before a 503 query_memory.",
    )
    sparql_max_rows: int = Field(
        100_000, gt=0, description="Most rows (or triples) one user SPARQL answer holds; more are cut off."
    )

    # --- HTTP servers ------------------------------------------------------------------------------------
    host: str = Field("127.0.0.1", description="Interface the API and UI listen on.")
    api_port: int = Field(5000, ge=0, le=65535, description="Port of the API.")
    api_workers: int = Field(
        1, ge=1, le=64, description="API processes on the API port (segb serve --workers); >1 needs a remote store."
    )
    ui_port: int = Field(8080, ge=0, le=65535, description="Port of the web UI.")
    backend_url: str = Field(
        "",
        description="URL the UI uses to reach the API; empty = http://127.0.0.1:<API_PORT>.",
    )
    forwarded_allow_ips: str = Field(
        "127.0.0.1",
        description="Comma-separated addresses of reverse proxies trusted for X-Forwarded-For/-Proto ('*' = any).",
    )
    cors_origins: str = Field("", description="Comma-separated origins allowed by CORS (empty = CORS off).")
    cors_allow_credentials: bool = Field(
        False, description="Let CORS requests from CORS_ORIGINS carry cookies and HTTP authentication."
    )

    # --- auth --------------------------------------------------------------------------------------------
    secret_key: str = Field("", description="HS256 secret for JWTs; empty = authentication disabled.")
    allow_weak_secret: bool = Field(False, description="Start even when SECRET_KEY is shorter than 32 chars.")

    # --- shared context ----------------------------------------------------------------------------------
    shared_context_namespace: str = Field(
        "https://gsi.upm.es/segb/shared-events/", description="Namespace of the shared-context URIs the server mints."
    )
    shared_context_time_window_seconds: float = Field(
        3.0, gt=0, description="Observations further apart than this score 0 on time (candidates within 2x)."
    )
    shared_context_match_threshold: float = Field(
        0.85, ge=0, le=1, description="Score from which an observation joins an existing shared context."
    )
    shared_context_ambiguous_threshold: float = Field(
        0.70, ge=0, le=1, description="Score from which a non-matching observation opens a review (ambiguous)."
    )
    shared_context_close_margin: float = Field(
        0.05, ge=0, le=1, description="Lead the best candidate needs over the second to match without review."
    )
    shared_context_strict_modality_mismatch: bool = Field(
        False, description="Never match observations whose modalities differ."
    )

    # --- operations --------------------------------------------------------------------------------------
    log_level: str = Field("INFO", validation_alias="LOGGING_LEVEL", description="Log level (LOGGING_LEVEL).")
    sparql_dir: Path = Field(PACKAGE_ROOT / "sparql", description="Directory of the .rq query files.")
    rules_dir: Path = Field(
        PACKAGE_ROOT / "rules", description="Directory of the audit rules (.rq SPARQL rules, .ttl SHACL shapes)."
    )
    server_log_file: str = Field(
        "", description="JSON-lines server log; empty = DATA_DIR/logs/server.jsonl (in memory with STORE=memory)."
    )
    server_log_max_bytes: int = Field(
        10 * 1024 * 1024, gt=0, description="Size at which the server log file is rotated."
    )
    server_log_backups: int = Field(3, ge=0, description="Rotated server log files kept (server.jsonl.1, .2, …).")

    # --- watching from operators' tools ----------------------------------------------------------------
    metrics_token: str = Field(
        "", description="A bearer token GET /metrics accepts besides an auditor's JWT (for a Prometheus scraper)."
    )
    webhook_urls: str = Field(
        "", description="Comma-separated URLs told of new and resolved findings (POST, JSON, signed); empty = none."
    )
    webhook_secret: str = Field("", description="Key of the webhooks' HMAC-SHA256 signature (X-SEGB-Signature).")
    webhook_min_severity: Literal["violation", "warning", "info"] = Field(
        "warning", description="Least serious finding a webhook is told of (violation > warning > info)."
    )
    otel_exporter_otlp_endpoint: str = Field(
        "",
        validation_alias="OTEL_EXPORTER_OTLP_ENDPOINT",
        description="OTLP/HTTP endpoint that live traces of what robots did are sent to (OpenTelemetry's own "
        "variable; its other OTEL_* settings apply too); empty = no live traces.",
    )
    trace_message_text: bool = Field(
        False, description="Put a message's text in its span (by default only its length is sent)."
    )

    @field_validator("graph_uri", "virtuoso_endpoint", "shared_context_namespace")
    @classmethod
    def _absolute_http_iri(cls, value: str) -> str:
        if not value.startswith(("http://", "https://")):
            raise ValueError("must be an absolute http(s) IRI")
        return value

    @field_validator("state_url")
    @classmethod
    def _postgresql_url(cls, value: str) -> str:
        if value and not value.startswith(("postgresql://", "postgres://")):
            raise ValueError("must be empty (SQLite in DATA_DIR) or a postgresql:// URL")
        return value

    @field_validator("retention_days", mode="before")
    @classmethod
    def _empty_is_forever(cls, value: object) -> object:
        return None if isinstance(value, str) and not value.strip() else value

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

    @model_validator(mode="after")
    def _webhooks_signed(self) -> Settings:
        if self.webhook_urls.strip() and len(self.webhook_secret) < MIN_SECRET_LENGTH:
            raise ValueError(f"WEBHOOK_URLS needs a WEBHOOK_SECRET of at least {MIN_SECRET_LENGTH} characters")
        for url in self.webhook_url_list:
            if not url.startswith(("http://", "https://")):
                raise ValueError(f"WEBHOOK_URLS: {url!r} is not an http(s) URL")
        return self

    @model_validator(mode="after")
    def _metrics_token_strength(self) -> Settings:
        if self.metrics_token and len(self.metrics_token) < MIN_SECRET_LENGTH and not self.allow_weak_secret:
            raise ValueError(f"METRICS_TOKEN must be at least {MIN_SECRET_LENGTH} characters")
        return self

    @model_validator(mode="after")
    def _retention_floor(self) -> Settings:
        days = self.retention_days
        if days is not None and days < MIN_RETENTION_DAYS and not self.allow_short_retention:
            raise ValueError(
                f"RETENTION_DAYS={days} is shorter than six months ({MIN_RETENTION_DAYS} days): the AI Act (Art. 19 "
                "and 26(6)) asks that the logs of a high-risk AI system, such as emotion recognition, be kept at "
                "least that long; set ALLOW_SHORT_RETENTION=true if that obligation does not apply to you"
            )
        return self

    @property
    def effective_ingest_ack(self) -> Literal["journal", "store"]:
        if self.ingest_ack != "auto":
            return self.ingest_ack
        return "store" if self.store_is_local else "journal"

    @property
    def store_is_local(self) -> bool:
        """The store lives in this server's process (embedded on disk, or in memory), not behind an endpoint."""
        return self.store in ("oxigraph", "memory")

    @property
    def effective_views_max_lag_seconds(self) -> float:
        """A remote store's views ask it queries it plans anew each batch
        (docs/performance.md#virtuoso-and-the-embedded-store), so their batches are dearer, and posts held at 1.5 s
        waited more often than at 2 (one robot on Virtuoso, 3 minutes: 60 posts/s against 75). Held at 2.5 s, 15
        minutes gave no more posts (56 a second) and slower pages. With a batch's time on top, the reports stay
        within 2 s of the embedded store and within 5 s of a remote one (the soak's bounds): held at 1.5 s, the
        embedded store's 15-minute soak had them 2.05 s behind at p99."""
        if self.views_max_lag_seconds is not None:
            return self.views_max_lag_seconds
        return 1.3 if self.store_is_local else 2.0

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
    def effective_server_log_file(self) -> Path | None:
        """Where the server log is written; None = kept in memory only (a throwaway STORE=memory server)."""
        if self.server_log_file:
            return Path(self.server_log_file)
        return None if self.store == "memory" else self.data_dir / "logs" / "server.jsonl"

    @property
    def webhook_url_list(self) -> list[str]:
        return [url.strip() for url in self.webhook_urls.split(",") if url.strip()]

    @property
    def cors_origin_list(self) -> list[str]:
        return [origin.strip() for origin in self.cors_origins.split(",") if origin.strip()]
