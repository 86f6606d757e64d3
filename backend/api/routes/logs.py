"""GET /logs/server: the structured server log, newest first, filtered by level and text (admin)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Admin, ServicesDep
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.ops.server_log import LEVELS

router = APIRouter(tags=["operations"])

MAX_ENTRIES = 1000
LEVEL_PATTERN = "(?i)^(" + "|".join(LEVELS) + ")$"


class LogEntry(BaseModel):
    time: str = Field(examples=["2026-03-10T09:00:05.123Z"])
    level: str
    logger: str = Field(examples=["segb.requests"])
    message: str
    request_id: str | None = None
    user: str | None = None
    method: str | None = None
    path: str | None = None
    status: int | None = None
    duration_ms: float | None = None
    triples_written: int | None = None
    log_id: str | None = Field(None, description="The ingest's `log_id` (as in its answer and the ledger).")
    exception: str | None = Field(None, description="Type and message of an error logged with its exception.")


class LogEntries(BaseModel):
    entries: list[LogEntry]
    source: str = Field(description="`file` (DATA_DIR/logs/server.jsonl and its backups) or `memory`.")


@router.get(
    "/logs/server",
    response_model=LogEntries,
    response_model_exclude_none=True,
    summary="Server log",
    description=(
        "The server's structured log, newest first: one entry per request (id, method, path, status, duration, "
        "user, triples written) and every warning or error of the server. `level` keeps that level and above; "
        "`contains` keeps entries holding that text in any field (any case). Reads the rotated backups too "
        "when `limit` needs them. Tokens and bodies are never logged."
    ),
)
def server_log(
    services: ServicesDep,
    principal: Admin,
    limit: int = Query(100, ge=1, le=MAX_ENTRIES, description=f"Most entries returned (1 to {MAX_ENTRIES})."),
    level: str = Query("DEBUG", pattern=LEVEL_PATTERN, description=f"Lowest level shown: {', '.join(LEVELS)}."),
    contains: str | None = Query(None, max_length=200, description="Text the entry must hold (any case)."),
) -> dict[str, Any]:
    # A plain `def` route runs in the thread pool, so reading the log files stays off the event loop.
    log = services.server_log
    if log is None:
        raise NotFound("This server keeps no log.")
    return {"entries": log.read(limit, level.upper(), contains), "source": log.source}
