"""UTC instants as the server writes them everywhere: ISO 8601 with a `Z`."""

from __future__ import annotations

import time
from datetime import UTC, datetime


def utc_iso(seconds: float | None = None, timespec: str = "microseconds") -> str:
    """`seconds` since the epoch (default: now) as e.g. `2026-03-10T09:00:05.123456Z`."""
    moment = datetime.fromtimestamp(time.time() if seconds is None else seconds, UTC)
    return moment.isoformat(timespec=timespec).replace("+00:00", "Z")
