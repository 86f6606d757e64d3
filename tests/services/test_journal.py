"""The journal on its own, in memory: posts chained in order with only their new triples, a clearing that forgets
them, entries read back as the applier reads them, the chain verified, the size limit held."""

from __future__ import annotations

import concurrent.futures
import threading
import uuid
from pathlib import Path

import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.services.ingest.service import post_entry
from segb_server.backend.services.writing import known_digests
from segb_server.backend.services.writing.journal import Journal, PostEntry, StorageFull
from segb_server.backend.services.writing.known_digests import KnownDigests
from segb_server.backend.services.writing.receipts import GENESIS_HASH
from segb_server.backend.state.sqlite import SqliteDatabase

EX = "https://example.org/"


def quad(subject: str, value: str) -> Quad:
    return Quad(NamedNode(EX + subject), NamedNode(EX + "says"), Literal(value))


def post(*quads: Quad, user: str = "ari") -> PostEntry:
    return post_entry(list(quads), user, None, "0" * 64)


@pytest.fixture
def journal() -> Journal:
    return Journal(SqliteDatabase(None))


def test_posts_are_chained_in_order_and_keep_only_their_new_triples(journal: Journal) -> None:
    first, again, more = journal.append_posts(
        [post(quad("a", "hi")), post(quad("a", "hi")), post(quad("a", "hi"), quad("b", "bye"))]
    )
    assert [r.sequence for r in (first, again, more)] == [1, 2, 3]  # type: ignore[union-attr]
    assert [(r.triples_received, r.triples_new) for r in (first, again, more)] == [(1, 1), (1, 0), (2, 1)]  # type: ignore[union-attr]
    assert first.previous_hash == GENESIS_HASH and again.previous_hash == first.receipt_hash  # type: ignore[union-attr]
    entries = journal.entries_after(0, 10)
    assert [entry.content for entry in entries] == [
        f'<{EX}a> <{EX}says> "hi" .\n'.encode(),
        b"",
        f'<{EX}b> <{EX}says> "bye" .\n'.encode(),
    ]
    assert journal.head() == 3 and [e.sequence for e in journal.entries_after(1, 1)] == [2]


def test_a_clearing_forgets_the_triples_so_they_may_come_again(journal: Journal) -> None:
    journal.append_posts([post(quad("a", "hi"), quad("b", "bye"))])
    cleared = journal.append_clear(log_id="clear-1", user="admin", claimed_user=None)
    (again,) = journal.append_posts([post(quad("a", "hi"))])
    assert (cleared.action, cleared.triples_removed) == ("delete_all", 2)
    assert again.triples_new == 1  # type: ignore[union-attr]
    assert journal.last_clearing() == 2
    assert list(journal.received_documents()) == [f'<{EX}a> <{EX}says> "hi" .\n'.encode()]  # since the clearing


def test_a_post_that_fails_alone_leaves_the_others_chained(journal: Journal) -> None:
    hostile = post(quad("evil", "x"), user="\ud800")  # a lone surrogate: legal in JSON, not storable text
    outcomes = journal.append_posts([post(quad("a", "hi")), hostile, post(quad("b", "bye"))])
    assert [type(outcome).__name__ for outcome in outcomes] == ["Receipt", "UnicodeEncodeError", "Receipt"]
    assert [outcome.sequence for outcome in outcomes if not isinstance(outcome, BaseException)] == [1, 2]
    assert journal.head() == 2 and journal.verify().valid
    (again,) = journal.append_posts([post(quad("evil", "x"))])
    assert again.triples_new == 1  # type: ignore[union-attr]  # nothing of the failed post was kept


def test_verify_finds_an_edited_receipt_and_an_edited_content(journal: Journal) -> None:
    journal.append_posts([post(quad("a", "hi")), post(quad("b", "bye"))])
    assert journal.verify(deep=True).valid and journal.verify().receipts == 2
    journal.database.execute("UPDATE receipts SET content = ? WHERE sequence = 2", (b"",))
    assert journal.verify().valid  # the receipts themselves are whole
    broken = journal.verify(deep=True).first_broken
    assert broken is not None and (broken.sequence, broken.reason) == (2, "content does not match")
    journal.database.execute("UPDATE receipts SET triples_new = 9 WHERE sequence = 1")
    broken = journal.verify().first_broken
    assert broken is not None and (broken.sequence, broken.reason) == (1, "hash mismatch")


def test_receipts_are_paged_newest_first_and_opened_by_log_id(journal: Journal) -> None:
    receipts = journal.append_posts([post(quad(str(n), "x")) for n in range(5)])
    page, total = journal.page(limit=2, offset=1)
    assert total == 5 and [r.sequence for r in page] == [4, 3]
    receipt, content = journal.entry(receipts[0].log_id)  # type: ignore[union-attr]
    assert receipt == receipts[0] and content == f'<{EX}0> <{EX}says> "x" .\n'.encode()


def test_past_its_size_limit_the_journal_refuses_the_post_and_keeps_nothing_of_it() -> None:
    journal = Journal(SqliteDatabase(None), max_bytes=32 * 1024)
    big = [quad(f"s{n}", uuid.uuid4().hex * 4) for n in range(1000)]  # random: no compression makes it fit
    with pytest.raises(StorageFull, match="JOURNAL_MAX_BYTES"):
        journal.append_posts([post(*big)])
    assert journal.head() == 0 and journal.storage_problem is not None


def test_the_digests_remembered_are_bounded_and_forgetting_one_loses_no_triple(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A robot logging for months: the journal remembers the digests of the triples re-sent lately, not of every
    triple ever posted; a triple no longer remembered is still known to the journal (its table decides)."""
    monkeypatch.setattr(known_digests, "GENERATION", 50)
    journal = Journal(SqliteDatabase(None))
    graph: list[Quad] = []
    for index in range(300):  # the client's way: the whole graph again, with one triple more each time
        graph.append(quad(f"n{index}", "new"))
        (receipt,) = journal.append_posts([post(*graph[-40:])])  # the last 40: a payload the bound holds
        assert receipt.triples_new == 1  # type: ignore[union-attr]
        assert len(journal._known) <= 100
    (again,) = journal.append_posts([post(graph[0], quad("late", "new"))])  # forgotten long ago, and a new one
    assert (again.triples_received, again.triples_new) == (2, 1)  # type: ignore[union-attr]
    assert journal.entries_after(again.sequence - 1, 1)[0].content == f'<{EX}late> <{EX}says> "new" .\n'.encode()  # type: ignore[union-attr]


def test_known_digests_keep_what_is_still_re_sent() -> None:
    known = KnownDigests(generation=3)
    known.update([b"a", b"b"])
    assert b"a" in known  # found in the current generation
    known.update([b"c", b"d", b"e"])  # a, b, c filled the current generation: the previous one now; d, e current
    assert b"a" in known  # re-sent: moved to the current one (d, e, a), which filled and became the previous one
    known.update([b"f", b"g"])
    assert len(known) == 5  # f, g and the previous d, e, a: b and c, not re-sent, were forgotten
    assert b"b" not in known and b"c" not in known and b"a" in known and b"g" in known


def test_reads_answer_from_the_last_commit_while_a_write_transaction_is_open(tmp_path: Path) -> None:
    """The applier reading the entries just recorded, and posts asking how far behind the store is, do not wait
    for the next batch's transaction (its commit syncs the disk): on a file they read through a connection of
    their own, and see what was committed."""
    journal = Journal(SqliteDatabase(tmp_path / "journal.sqlite3"))
    journal.append_posts([post(quad("a", "hi"))])
    writing, release = threading.Event(), threading.Event()

    def hold_a_write_transaction() -> None:
        with journal.database.writing():
            journal.database.execute("UPDATE receipts SET triples_new = 7 WHERE sequence = 1")
            writing.set()
            release.wait(10)

    writer = threading.Thread(target=hold_a_write_transaction)
    writer.start()
    try:
        assert writing.wait(5)
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            reads = pool.submit(lambda: (journal.head(), journal.entries_after(0, 10), journal.page(10, 0)))
            head, entries, (receipts, total) = reads.result(timeout=5)  # before the fix: blocked until release
        assert head == 1 and [entry.sequence for entry in entries] == [1] and total == 1
        assert receipts[0].triples_new == 1  # the committed state, not the open transaction's
    finally:
        release.set()
        writer.join()
    assert journal.page(10, 0)[0][0].triples_new == 7
    journal.append_posts([post(quad("b", "bye"))])
    assert journal.head() == 2 and journal.entries_after(1, 10)[0].content == f'<{EX}b> <{EX}says> "bye" .\n'.encode()
    journal.close()
