"""The journal's file is `DATA_DIR/journal.sqlite3`; a data directory still holding it under its former name,
`ledger.sqlite3`, has it renamed once when a server starts on it, commits still in its write-ahead log included,
and the log says so."""

from __future__ import annotations

import logging
import shutil
import sqlite3
from pathlib import Path

import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.services.writing.journal_file import (
    FORMER_JOURNAL_FILE,
    JOURNAL_FILE,
    JournalInUse,
    journal_path,
)
from tests.conftest import make_settings
from tests.support.in_process import InProcess

TRIPLE = '<https://example.org/s{}> <https://example.org/p> "v" .'


def serve_and_post(data_dir: Path, posts: int) -> list[str]:
    """Start a server on `data_dir`, post `posts` triples one by one; the receipts' ids, oldest first."""
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=data_dir))) as api:
        for number in range(posts):
            answer = api.post("/ttl", content=TRIPLE.format(number), headers={"Content-Type": "application/n-triples"})
            assert answer.status_code == 201, answer.text
        return [receipt["log_id"] for receipt in reversed(api.get("/ledger").json()["receipts"])]


def receipts_after_restart(data_dir: Path) -> tuple[list[str], bool]:
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=data_dir))) as api:
        verified = api.get("/ledger/verify", params={"deep": "true"}).json()["valid"]
        return [receipt["log_id"] for receipt in reversed(api.get("/ledger").json()["receipts"])], verified


def test_a_server_on_a_data_directory_of_the_former_name_renames_its_journal_once_and_says_so(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    posted = serve_and_post(tmp_path, 3)
    (tmp_path / JOURNAL_FILE).rename(tmp_path / FORMER_JOURNAL_FILE)  # a data directory of an earlier version

    with caplog.at_level(logging.INFO, logger="segb.journal"):
        receipts, valid = receipts_after_restart(tmp_path)
        again, _ = receipts_after_restart(tmp_path)
    assert receipts == posted == again and valid
    assert (tmp_path / JOURNAL_FILE).is_file() and not (tmp_path / FORMER_JOURNAL_FILE).exists()
    said = [record.getMessage() for record in caplog.records if FORMER_JOURNAL_FILE in record.getMessage()]
    assert len(said) == 1 and f"renamed {JOURNAL_FILE}" in said[0]


def test_commits_still_in_the_write_ahead_log_move_with_the_file(tmp_path: Path) -> None:
    """A server of the earlier version stopped by a crash leaves commits in `ledger.sqlite3-wal` only."""
    posted = serve_and_post(tmp_path / "before", 2)
    crashed = tmp_path / "crashed"
    crashed.mkdir()
    writer = sqlite3.connect(tmp_path / "before" / JOURNAL_FILE)
    writer.execute("PRAGMA wal_autocheckpoint=0")  # the next commit stays in the log, as a crash would leave it
    writer.execute("UPDATE receipts SET claimed_user = 'in the log only' WHERE sequence = 2")
    writer.commit()
    shutil.copy(tmp_path / "before" / JOURNAL_FILE, crashed / FORMER_JOURNAL_FILE)
    shutil.copy(tmp_path / "before" / f"{JOURNAL_FILE}-wal", crashed / f"{FORMER_JOURNAL_FILE}-wal")
    writer.close()

    path = journal_path(crashed)
    assert sorted(file.name for file in crashed.iterdir()) == [JOURNAL_FILE, f"{JOURNAL_FILE}.lock"]
    journal = sqlite3.connect(path)
    claimed = journal.execute("SELECT claimed_user FROM receipts WHERE sequence = 2").fetchone()[0]
    journal.close()
    assert claimed == "in the log only" and len(posted) == 2


def test_a_journal_of_the_former_name_open_in_another_process_is_left_alone(tmp_path: Path) -> None:
    serve_and_post(tmp_path, 1)
    (tmp_path / JOURNAL_FILE).rename(tmp_path / FORMER_JOURNAL_FILE)
    holder = sqlite3.connect(tmp_path / FORMER_JOURNAL_FILE)  # a running server of the earlier version
    holder.execute("SELECT COUNT(*) FROM receipts").fetchone()
    try:
        with pytest.raises(JournalInUse, match="open in another process"):
            journal_path(tmp_path)
    finally:
        holder.close()
    assert (tmp_path / FORMER_JOURNAL_FILE).is_file() and not (tmp_path / JOURNAL_FILE).exists()
