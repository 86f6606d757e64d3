"""A view's table of terms (`views/terms.py`): texts as small numbers, found by a hash and told apart by the
text itself, or (the kept rows' table) by a 128-bit digest that keeps no text at all."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from segb_server.backend.services.views import terms
from segb_server.backend.services.views.kept_queries.rows import KeptRows
from segb_server.backend.services.views.kept_queries.rows_database import TERMS
from segb_server.backend.services.views.terms import TermIds, iri_digest, iri_hash

IRIS = [f"https://example.org/robots/ari/visitor_{index}" for index in range(1_000)]


def table(texts: bool) -> sqlite3.Connection:
    connection = sqlite3.connect(":memory:")
    for statement in terms.schema("t", texts=texts):
        connection.execute(statement)
    return connection


@pytest.mark.parametrize("texts", [True, False], ids=["texts", "digests"])
def test_each_text_gets_one_number_that_every_writer_and_reader_finds_again(texts: bool) -> None:
    connection = table(texts)
    made = TermIds("t", texts=texts).ids(connection, IRIS)
    assert sorted(made.values()) == list(range(1, len(IRIS) + 1))
    again = TermIds("t", texts=texts).ids(connection, [*reversed(IRIS), "https://example.org/new"])  # a new writer
    assert {iri: again[iri] for iri in IRIS} == made and again["https://example.org/new"] == len(IRIS) + 1
    assert terms.lookup(connection, "t", [IRIS[5], "https://example.org/never"], texts=texts) == {
        IRIS[5]: made[IRIS[5]]
    }


def test_a_table_of_digests_holds_no_text() -> None:
    connection = table(texts=False)
    TermIds("t", texts=False).ids(connection, IRIS)
    columns = {row[1] for row in connection.execute("PRAGMA table_info(t)")}
    assert columns == {"id", "hash", "tail"}
    # the rows are kept in their digests' order: no index of them beside the table
    assert connection.execute("SELECT name FROM sqlite_master WHERE type = 'index'").fetchall() == []
    dumped = "\n".join(connection.iterdump())
    assert "visitor_" not in dumped and "example.org" not in dumped


@pytest.mark.parametrize("texts", [True, False], ids=["texts", "digests"])
def test_two_texts_sharing_a_hash_keep_their_own_numbers(texts: bool) -> None:
    connection = table(texts)
    # another text whose hash (the indexed half) is this IRI's: written first, as a collision would be
    head = iri_hash(IRIS[0]) if texts else iri_digest(IRIS[0])[0]
    other = "https://example.org/another" if texts else iri_digest(IRIS[0])[1] ^ 1
    if texts:
        connection.execute("INSERT INTO t (hash, text) VALUES (?, ?)", (head, other))
    else:
        connection.execute("INSERT INTO t (hash, tail, id) VALUES (?, ?, 1)", (head, other))
        connection.execute("UPDATE t_made SET made = 1")
    made = TermIds("t", texts=texts).ids(connection, [IRIS[0]])
    assert made[IRIS[0]] == 2
    assert terms.lookup(connection, "t", [IRIS[0]], texts=texts) == {IRIS[0]: 2}


def test_numbers_made_in_a_transaction_that_rolled_back_are_made_again(tmp_path: Path) -> None:
    """A report's write that fails (a full disk) rolls back the numbers it made and the count they came from: the
    writer must not go on using them, or the next text would get a number another already has in its memory."""
    rows = KeptRows(tmp_path / "reports.sqlite3")
    try:
        with pytest.raises(sqlite3.OperationalError), rows.db.writing() as connection:
            first = rows.terms.ids(connection, IRIS[:3])
            rows.namespaces.for_writing(connection, "report_x", IRIS[:3])  # a table's first keys' namespaces
            raise sqlite3.OperationalError("database or disk is full")
        with rows.db.writing() as connection:
            again = rows.terms.ids(connection, [IRIS[3], *IRIS[:3]])
            written = rows.namespaces.for_writing(connection, "report_x", IRIS[:3])
        # the namespaces rows are written with are those a reader finds (made again, not remembered)
        assert rows.namespaces.for_reading(rows.db.reader(), "report_x").entries == written.entries != ()
        assert len(set(again.values())) == 4, again  # four texts, four numbers
        assert terms.lookup(rows.db.reader(), TERMS, IRIS[:4], texts=False) == again  # what the table holds
        assert first  # they had been made, in the transaction that rolled back
    finally:
        rows.db.close()
