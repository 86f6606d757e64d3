"""What the kept rows keep per table beside them (a dictionary, namespaces) goes with that table's rows."""

from __future__ import annotations

import sqlite3
from collections.abc import Collection
from typing import Any


def forget(
    connection: sqlite3.Connection, kept_in: str, remembered: dict[str, Any], tables: Collection[str] | None
) -> None:
    """Delete the rows of `kept_in` about `tables` (about every table: None), and what the writer
    `remembered` of them, inside the writer's transaction that empties or drops those tables."""
    if tables is None:
        connection.execute(f"DELETE FROM {kept_in}")
        remembered.clear()
        return
    for table in tables:
        connection.execute(f"DELETE FROM {kept_in} WHERE tab = ?", (table,))
        remembered.pop(table, None)


def dropped(connection: sqlite3.Connection, kept_in: str, tables: Collection[str]) -> set[str]:
    """The tables `kept_in` has rows about, but `tables` (the tables kept)."""
    return {row[0] for row in connection.execute(f"SELECT DISTINCT tab FROM {kept_in}")} - set(tables)
