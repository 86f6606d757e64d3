"""Kept rows compressed against a dictionary of their table's first rows (`kept_queries/row_codec.py`): text until
the table holds enough rows to make one, then compressed; read back by any codec (another process's) from the
database alone; and read consistently by many threads while the writer empties, drops and refills the table,
making new dictionaries each time."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.kept_queries import row_codec
from segb_server.backend.services.views.kept_queries.row_codec import SAMPLE_ROWS, RowCodec, schema

TABLE = "report_example"
CREATE = f"CREATE TABLE IF NOT EXISTS {TABLE} (unit INTEGER, row)"


def row(generation: int, index: int) -> str:
    return json.dumps([f"https://example.org/robots/ari/message/{generation}/{index}", "Hello ARI", index])


def write(database: ViewDatabase, codec: RowCodec, generation: int, indexes: range, *, fresh: bool = False) -> None:
    with database.writing() as connection:
        if fresh:  # as a build does: the table and its dictionary go together
            connection.execute(f"DROP TABLE IF EXISTS {TABLE}")
            codec.forget(connection, [TABLE])
            connection.execute(CREATE)
        texts = [row(generation, index) for index in indexes]
        stored = codec.encode(connection, TABLE, texts)
        connection.executemany(f"INSERT INTO {TABLE} VALUES (?, ?)", [(generation, value) for value in stored])


def read(database: ViewDatabase, codec: RowCodec) -> list[str]:
    with database.snapshot() as connection:
        return [codec.decode(connection, value) for (value,) in connection.execute(f"SELECT row FROM {TABLE}")]


def test_rows_are_text_until_the_table_makes_its_dictionary_then_compressed(tmp_path: Path) -> None:
    database = ViewDatabase(tmp_path / "view.sqlite3", [*schema(), CREATE])
    try:
        writer = RowCodec()
        write(database, writer, 0, range(SAMPLE_ROWS - 1))
        write(database, writer, 0, range(SAMPLE_ROWS - 1, SAMPLE_ROWS + 200))
        stored = [value for (value,) in database.reader().execute(f"SELECT row FROM {TABLE}")]
        assert all(isinstance(value, str) for value in stored[: SAMPLE_ROWS - 1])
        compressed = [value for value in stored[SAMPLE_ROWS - 1 :] if isinstance(value, bytes)]
        assert len(compressed) == 201
        assert sum(map(len, compressed)) * 4 < sum(len(row(0, index)) for index in range(SAMPLE_ROWS - 1, 264))
        # another codec (another process's) reads them from the database alone
        assert read(database, RowCodec()) == [row(0, index) for index in range(SAMPLE_ROWS + 200)]
    finally:
        database.close()


def test_readers_read_whole_versions_while_the_writer_rebuilds_the_table(tmp_path: Path) -> None:
    database = ViewDatabase(tmp_path / "view.sqlite3", [*schema(), CREATE])
    writer, reader_codec = RowCodec(), RowCodec()
    rebuilt = threading.Event()
    failures: list[BaseException] = []
    seen: list[int] = []
    last: list[int] = []

    def rebuild() -> None:
        try:
            generation = 0
            while len(seen) < 300 and generation < 5_000:  # until the readers have read many versions
                generation += 1
                write(database, writer, generation, range(SAMPLE_ROWS + 20), fresh=True)
                write(database, writer, generation, range(SAMPLE_ROWS + 20, SAMPLE_ROWS + 40))
            last.append(generation)
        except BaseException as error:  # reported by the test
            failures.append(error)
        finally:
            rebuilt.set()

    def follow() -> None:
        try:
            while not rebuilt.is_set():
                rows = read(database, reader_codec)
                generations = {json.loads(text)[0].split("/")[-2] for text in rows}
                assert len(generations) <= 1, generations  # one version: never two builds' rows at once
                seen.append(len(rows))
        except BaseException as error:  # reported by the test
            failures.append(error)

    try:
        write(database, writer, 0, range(SAMPLE_ROWS + 40), fresh=True)
        threads = [*(threading.Thread(target=follow) for _ in range(4)), threading.Thread(target=rebuild)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(timeout=120)
        assert failures == []
        assert len(seen) >= 300 and max(seen) == SAMPLE_ROWS + 40
        final = read(database, RowCodec())
        assert final == [row(last[0], index) for index in range(SAMPLE_ROWS + 40)]
        dictionaries = database.reader().execute("SELECT COUNT(*) FROM report_dictionaries").fetchone()[0]
        assert dictionaries == 1  # each build's dictionary went with its rows
    finally:
        database.close()


def test_rows_read_in_a_snapshot_are_decoded_with_their_own_versions_dictionary(tmp_path: Path) -> None:
    """A page reads its rows, then their dictionary: a build committed in between (its table and dictionary
    replaced) must not leave the page with rows whose dictionary is gone."""
    database = ViewDatabase(tmp_path / "view.sqlite3", [*schema(), CREATE])
    try:
        writer = RowCodec()
        write(database, writer, 1, range(SAMPLE_ROWS + 20), fresh=True)
        with database.snapshot() as connection:
            stored = [value for (value,) in connection.execute(f"SELECT row FROM {TABLE}")]
            write(database, writer, 2, range(SAMPLE_ROWS + 20), fresh=True)  # committed meanwhile
            texts = [RowCodec().decode(connection, value) for value in stored]
        assert texts == [row(1, index) for index in range(SAMPLE_ROWS + 20)]
        assert read(database, RowCodec()) == [row(2, index) for index in range(SAMPLE_ROWS + 20)]
        # outside a snapshot, the old version's dictionary is gone
        with pytest.raises(LookupError):
            RowCodec().decode(database.reader(), stored[-1])
    finally:
        database.close()


def test_rows_compressed_at_zlibs_default_memory_level_read_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Earlier versions compressed at zlib's default memory level (8): a data directory they wrote reads alike."""
    database = ViewDatabase(tmp_path / "view.sqlite3", [*schema(), CREATE])
    try:
        monkeypatch.setattr(row_codec, "MEMORY_LEVEL", 8)
        write(database, RowCodec(), 0, range(SAMPLE_ROWS + 50))
        monkeypatch.undo()
        stored = [value for (value,) in database.reader().execute(f"SELECT row FROM {TABLE}")]
        assert all(isinstance(value, bytes) for value in stored)  # enough rows for a dictionary in one write
        assert read(database, RowCodec()) == [row(0, index) for index in range(SAMPLE_ROWS + 50)]
    finally:
        database.close()
