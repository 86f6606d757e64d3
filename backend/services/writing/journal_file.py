"""Where the journal's SQLite file is: `DATA_DIR/journal.sqlite3`, renamed once from the name it had before.

The journal grew out of the ingest ledger and kept its file, `ledger.sqlite3`, while the API called it the ledger
and the docs the journal. A server (or `segb copy-state`) opening a data directory that still holds the file
under that name renames it first: its write-ahead log folded into it, then one atomic rename, said in the log.
"""

from __future__ import annotations

import logging
import os
import sqlite3
from pathlib import Path

from segb_server.backend.services.errors import ServiceError
from segb_server.backend.state.file_lock import FileLock

JOURNAL_FILE = "journal.sqlite3"
FORMER_JOURNAL_FILE = "ledger.sqlite3"
SQLITE_COMPANIONS = ("-wal", "-shm")  # SQLite removes them when the last connection to the file closes

logger = logging.getLogger("segb.journal")


class JournalInUse(ServiceError):
    """The journal under its former name is open in another process: it cannot be renamed under it."""

    code = "journal_in_use"


def journal_path(data_dir: Path) -> Path:
    """The journal's file in `data_dir`, renamed from its former name first when that is what the directory holds.
    Done under the lock the journal's writers queue on, so API workers starting together rename it once."""
    path = data_dir / JOURNAL_FILE
    former = data_dir / FORMER_JOURNAL_FILE
    if not former.exists():
        return path
    lock = FileLock(data_dir / f"{JOURNAL_FILE}.lock")
    try:
        with lock.held():
            if not former.exists():  # another process renamed it meanwhile
                return path
            if path.exists():
                logger.warning("both %s and %s are in %s: the journal is the first, the other is left as it is",
                               JOURNAL_FILE, FORMER_JOURNAL_FILE, data_dir)  # fmt: skip
                return path
            _rename(former, path)
    finally:
        lock.close()
    return path


def _rename(former: Path, path: Path) -> None:
    # Commits still in the write-ahead log go into the file first: the log is named after the file, so a rename
    # alone would leave them behind.
    connection = sqlite3.connect(former)
    try:
        busy = connection.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchone()[0]
    finally:
        connection.close()
    left = [former.with_name(former.name + suffix) for suffix in SQLITE_COMPANIONS]
    if busy or any(companion.exists() for companion in left):
        raise JournalInUse(
            f"{former} is open in another process (a server of an earlier version?): stop it, then start again "
            f"to rename the journal's file {JOURNAL_FILE}"
        )
    os.rename(former, path)  # atomic: the journal is under one name or the other, whole, at every moment
    former.with_name(f"{former.name}.lock").unlink(missing_ok=True)
    logger.warning(
        "the journal's file %s in %s was renamed %s (its name since this version; nothing in it changed)",
        FORMER_JOURNAL_FILE,
        path.parent,
        JOURNAL_FILE,
    )
