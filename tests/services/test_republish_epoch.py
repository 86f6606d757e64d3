"""What lets a re-publish skip blocks without parsing them: the journal's epoch, shared by every process on one
data directory. A post read in an epoch a clearing (here another process's) has ended is refused by the journal,
recording nothing, and the ingest reads it again whole; the blocks a post counts as held are in its receipt."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import NamedNode, Quad

from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.writing.journal import EpochMoved, Journal
from segb_server.backend.state.sqlite import SqliteDatabase

QUAD = Quad(NamedNode("https://example.org/a"), NamedNode("https://example.org/p"), NamedNode("https://example.org/b"))


def test_a_post_read_before_another_process_cleared_is_refused_and_records_nothing(tmp_path: Path) -> None:
    mine, theirs = (Journal(SqliteDatabase(tmp_path / "journal.sqlite3")) for _ in range(2))
    epoch = mine.epoch()
    theirs.append_clear(log_id="clear", user="admin", claimed_user=None)

    [outcome] = mine.append_posts([post_entry([QUAD], "ari", None, "0" * 64, held=10, epoch=epoch)])

    assert isinstance(outcome, EpochMoved)
    assert mine.epoch() == epoch + 1
    assert mine.head() == 1  # the clearing alone


def test_a_post_counts_the_triples_it_held_as_received(tmp_path: Path) -> None:
    journal = Journal(SqliteDatabase(tmp_path / "journal.sqlite3"))

    [receipt] = journal.append_posts([post_entry([QUAD], "ari", None, "0" * 64, held=10, epoch=journal.epoch())])

    assert not isinstance(receipt, BaseException)
    assert (receipt.triples_received, receipt.triples_new) == (11, 1)
    assert journal.holds([post_entry([QUAD], "ari", None, "").digests[0]])
