"""The state database the settings name: PostgreSQL when STATE_URL is set, else a SQLite file in DATA_DIR."""

from __future__ import annotations

from pathlib import Path

from segb_server.backend.state.database import Database
from segb_server.backend.state.sqlite import SqliteDatabase


def open_state(state_url: str, path: Path | None, *, writers: str, sync_full: bool = False) -> Database:
    """`path` is the SQLite file (None: memory); `writers` names the lock writers of this state queue on."""
    if state_url:
        from segb_server.backend.state.postgres import PostgresDatabase  # psycopg loads only where it is used

        return PostgresDatabase(state_url, writers=writers)
    return SqliteDatabase(path, sync_full=sync_full)
