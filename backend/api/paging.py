"""Paging parameters shared by the listing routes."""

from __future__ import annotations

from typing import Annotated

from fastapi import Query

# Far beyond any real result, and small enough for every store and SQLite (64-bit signed integers).
MAX_OFFSET = 1_000_000_000

Offset = Annotated[int, Query(ge=0, le=MAX_OFFSET, description="Rows to skip")]
