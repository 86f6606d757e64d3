"""Apply leadership epochs: a fencing token for the process that applies the journal, kept in the journal's state.

With the state in PostgreSQL, the process that takes the apply leadership (`SharedLeadership`) draws the next
epoch, one above every epoch before, and writes with it. A leader whose connection dropped may not know yet that
it lost the lead; its writes carry its older epoch, and what they would change refuses them: the store (its
cursor records the newest epoch that wrote it, `Store.apply(..., epoch=)`) and the journal's own state
(`refuse_older_epoch`, inside the journal's write transaction).
"""

from __future__ import annotations

from typing import Any

from segb_server.backend.state.database import Database

APPLY_LOCK = "applier"  # the name of the apply leadership's lock, and of its epoch's row
JOURNAL_WRITERS = "journal"  # the lock the journal's writers queue on (`PostgresDatabase(writers=…)`)
# The row's table is the journal's (created by the journal too: whichever comes first creates it, under the same
# lock as the journal's writers, so neither races the other).
_TABLE = "CREATE TABLE IF NOT EXISTS journal_state (name TEXT PRIMARY KEY, value BIGINT NOT NULL)"


class StateFenced(Exception):
    """A write of an apply epoch older than the journal's state holds: its writer lost the apply leadership."""

    def __init__(self, epoch: int, newer: int) -> None:
        super().__init__(f"the journal's state holds apply epoch {newer}, newer than this writer's {epoch}")
        self.epoch, self.newer = epoch, newer


def epoch_row(lock: str) -> str:
    return f"epoch:{lock}"


def next_epoch(connection: Any, lock: str) -> int:
    """Draw the next epoch of leadership `lock` on a psycopg connection (autocommit), in one transaction queued
    with the journal's writers: a journal write that checks the epoch runs wholly before it or after it."""
    from segb_server.backend.state.postgres import lock_key

    with connection.transaction():
        connection.execute("SELECT pg_advisory_xact_lock(%s)", (lock_key(JOURNAL_WRITERS),))
        connection.execute(_TABLE)
        row = connection.execute(
            "INSERT INTO journal_state (name, value) VALUES (%s, 1) "
            "ON CONFLICT (name) DO UPDATE SET value = journal_state.value + 1 RETURNING value",
            (epoch_row(lock),),
        ).fetchone()
    return int(row[0])


def draw_beyond(connection: Any, lock: str, seen: int) -> int | None:
    """An epoch above `seen` when this database never drew `seen` (its state restored from an older backup, or
    the store written under another database): None when it did, and `seen` is a newer leader's."""
    from segb_server.backend.state.postgres import lock_key

    with connection.transaction():
        connection.execute("SELECT pg_advisory_xact_lock(%s)", (lock_key(JOURNAL_WRITERS),))
        row = connection.execute("SELECT value FROM journal_state WHERE name = %s", (epoch_row(lock),)).fetchone()
        if row is not None and int(row[0]) >= seen:
            return None
        connection.execute("UPDATE journal_state SET value = %s WHERE name = %s", (seen + 1, epoch_row(lock)))
    return seen + 1


def refuse_older_epoch(connection: Database, epoch: int, lock: str = APPLY_LOCK) -> None:
    """Inside a write transaction of the journal: StateFenced unless `epoch` is still the newest drawn."""
    row = connection.execute("SELECT value FROM journal_state WHERE name = ?", (epoch_row(lock),)).fetchone()
    newest = int(row[0]) if row else 0
    if newest > epoch:
        raise StateFenced(epoch, newest)
