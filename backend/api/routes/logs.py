"""GET /logs/server: the structured server log, newest first, filtered by level and text (admin).

The answer is a superset of the reference backend's (`log_file`, `count`, `filters`, and per entry `timestamp`,
`actor`, `origin_ip`, `raw`), so its web UI reads it too."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Admin, ServicesDep
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.ops.server_log import LEVELS

router = APIRouter(tags=["operations"])

MAX_ENTRIES = 2000  # the reference's cap, which its web UI lets users ask for
LEVEL_PATTERN = "(?i)^(" + "|".join(LEVELS) + ")?$"  # blank: no filter, as the reference takes it


class LogEntry(BaseModel):
    time: str = Field(examples=["2026-03-10T09:00:05.123Z"])
    level: str
    logger: str = Field(examples=["segb.requests"])
    message: str
    process: int | None = Field(None, description="The pid of the API process that wrote it (one of its workers).")
    request_id: str | None = None
    user: str | None = None
    origin_ip: str | None = Field(None, description="The client's address (the TCP peer) of a request entry.")
    method: str | None = None
    path: str | None = None
    status: int | None = None
    duration_ms: float | None = None
    triples_written: int | None = None
    log_id: str | None = Field(None, description="The ingest's `log_id` (as in its answer and the ledger).")
    exception: str | None = Field(None, description="Type and message of an error logged with its exception.")
    timestamp: str | None = Field(None, description="The reference's name for `time`.")
    actor: str | None = Field(None, description="The reference's name for `user`.")
    raw: str = Field(description="The entry's line in the log file (JSON).")


class Filters(BaseModel):
    limit: int
    level: str | None = Field(description="The lowest level shown, upper-case; null when not filtered.")
    contains: str | None


class LogEntries(BaseModel):
    log_file: str | None = Field(description="Absolute path of the current log file; null when kept in memory.")
    count: int = Field(description="Number of entries returned.")
    total: int = Field(
        description=f"Entries that match the filters, counted up to {MAX_ENTRIES:,} or to this page's end, "
        "whichever is further (a page says `1\u201350 of 153`)."
    )
    more: bool = Field(description="True when more entries match than `total` counts.")
    filters: Filters = Field(description="The filters applied, normalised.")
    entries: list[LogEntry]
    source: str = Field(description="`file` (DATA_DIR/logs/server.jsonl and its backups) or `memory`.")


@router.get(
    "/logs/server",
    response_model=LogEntries,
    summary="Server log",
    description=(
        "The server's structured log, newest first: one entry per request (id, method, path, status, duration, "
        "user, client address, triples written) and every warning or error of the server. `level` keeps that "
        "level and above (blank: every level); `contains` keeps entries holding that text in any field (any "
        "case); `offset` skips that many of the matching entries (the next page starts at `offset + limit`); "
        f"`total` counts the matching entries up to {MAX_ENTRIES:,} (`more` when there are more). "
        "Reads the rotated backups too when the count or the page needs them. Tokens and bodies are never logged. "
        "The reference backend's fields are there too: `log_file`, `count`, `filters`, and per entry "
        "`timestamp`, `actor`, `origin_ip` and `raw`."
    ),
)
def server_log(
    services: ServicesDep,
    principal: Admin,
    limit: int = Query(100, ge=1, le=MAX_ENTRIES, description=f"Most entries returned (1 to {MAX_ENTRIES})."),
    level: str | None = Query(
        None, pattern=LEVEL_PATTERN, description=f"Lowest level shown: {', '.join(LEVELS)} (any case)."
    ),
    contains: str | None = Query(None, max_length=200, description="Text the entry must hold (any case)."),
    offset: int = Query(
        0, ge=0, le=MAX_ENTRIES, description=f"Matching entries to skip, newest first (0 to {MAX_ENTRIES}): pages."
    ),
) -> dict[str, Any]:
    # A plain `def` route runs in the thread pool, so reading the log files stays off the event loop.
    log = services.server_log
    if log is None:
        raise NotFound("This server keeps no log.")
    lowest = level.upper() if level else None
    needle = contains.strip() if contains and contains.strip() else None
    counted = max(offset + limit, MAX_ENTRIES)
    found = log.read(counted + 1, lowest or LEVELS[0], needle)
    entries = found[offset : offset + limit]
    return {
        "log_file": log.file,
        "count": len(entries),
        "total": min(len(found), counted),
        "more": len(found) > counted,
        "filters": {"limit": limit, "level": lowest, "contains": needle},  # the reference's three
        "entries": entries,
        "source": log.source,
    }
