"""Copying the server's state from one database into another, row for row: how a deployment moves its
journal and shared contexts from SQLite in DATA_DIR into PostgreSQL (`segb copy-state`). The journal's receipts
keep their sequences, hashes and content, so the copy verifies as the original did and the chain continues."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from segb_server.backend.state.database import Database

JOURNAL_TABLES = ("receipts", "journal_triples", "journal_state", "erased_triples", "erasure_pending")
CONTEXT_TABLES = ("contexts", "observations", "aliases", "cases", "rejected_pairs", "withheld_observations")
ROWS_PER_INSERT = 200


class TargetNotEmpty(Exception):
    """The target already holds state: a copy would mix two histories."""


def copy_tables(
    source: Database, target: Database, tables: Sequence[str], progress: Callable[[int], None] = lambda _rows: None
) -> dict[str, int]:
    """Copy `tables` (present in the target and empty there; one the source lacks copies nothing) in one
    transaction of the target's writers; returns the rows copied per table. `progress` hears of every batch."""
    copied: dict[str, int] = {}
    with target.writing():
        for table in tables:
            if target.execute(f"SELECT 1 FROM {table} LIMIT 1").fetchone() is not None:
                raise TargetNotEmpty(f"the target's table {table} is not empty")
        for table in tables:
            copied[table] = _copy_table(source, target, table, progress)
            target.continue_serials(table)
    return copied


def _copy_table(source: Database, target: Database, table: str, progress: Callable[[int], None]) -> int:
    columns = sorted(source.columns(table))
    if not columns:  # a table the version that wrote the source did not have yet: nothing to copy
        return 0
    names = ", ".join(f'"{column}"' for column in columns)  # quoted: `user` is a reserved word in PostgreSQL
    row_marks = f"({', '.join('?' for _ in columns)})"
    count = 0
    batch: list[object] = []

    def flush(rows: int) -> None:
        target.execute(f"INSERT INTO {table} ({names}) VALUES {', '.join([row_marks] * rows)}", batch)
        batch.clear()
        progress(rows)

    with source.reading():
        for row in source.execute(f"SELECT {names} FROM {table}"):
            batch.extend(row)
            count += 1
            if count % ROWS_PER_INSERT == 0:
                flush(ROWS_PER_INSERT)
        if batch:
            flush(len(batch) // len(columns))
    return count
