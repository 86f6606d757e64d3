"""The kept rows (reports, timeline, findings) are stored compressed against a dictionary made of their own
table's first rows, and their sort keys spell IRIs without the table's namespaces: one robot's visits take a
fraction of their text on disk, every page reads as before, and the dictionaries, which quote rows, never
outlive them: an erased visitor is in none."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.services.upkeep.kept_queries.key_namespaces import KEY_NAMESPACES
from segb_server.backend.services.upkeep.kept_queries.row_codec import DICTIONARIES, SAMPLE_ROWS, RowCodec
from segb_server.examples.receptionist import log_visit, receptionist
from tests.conftest import make_settings
from tests.support.in_process import InProcess
from tests.support.settle import settle

VISITS = 70  # more than SAMPLE_ROWS conversations: the tables get their dictionaries
ERASED = 7  # a visitor among the first rows, the ones the dictionaries are made of


@dataclass
class Kept:
    """What one view database holds: its dictionaries' samples and its rows, as stored and as read back."""

    samples: list[bytes]
    stored: dict[str, list[str | bytes]]  # table → its rows as stored
    texts: dict[str, list[str]]  # table → its rows read back


def kept(database: Path) -> Kept:
    with sqlite3.connect(database) as connection:
        samples = [bytes(row[0]) for row in connection.execute(f"SELECT sample FROM {DICTIONARIES}")]
        tables = [row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        with_rows = [table for table in tables if "row" in columns(connection, table) and table != DICTIONARIES]
        stored = {table: [row[0] for row in connection.execute(f"SELECT row FROM {table}")] for table in with_rows}
        codec = RowCodec()
        texts = {table: [codec.decode(connection, row) for row in rows] for table, rows in stored.items()}
    return Kept(samples, stored, texts)


def columns(connection: sqlite3.Connection, table: str) -> set[str]:
    return {row[1] for row in connection.execute(f'PRAGMA table_info("{table}")')}


def views(data_dir: Path) -> dict[str, Kept]:
    return {name: kept(data_dir / name) for name in ("reports.sqlite3", "timeline.sqlite3", "findings.sqlite3")}


@pytest.fixture
def server(tmp_path: Path) -> Iterator[tuple[httpx.Client, Path]]:
    data_dir = tmp_path / "data"
    logger = receptionist()  # the PyPI client, re-sending its whole graph as a robot's log grows
    with InProcess(create_app(make_settings(store="oxigraph", data_dir=data_dir))) as served:
        for index in range(VISITS):
            log_visit(logger, index, datetime(2026, 1, 5, 8, 0, tzinfo=UTC) + timedelta(seconds=7 * index))
            if index % 10 == 9:
                post(served.client, logger.graph.serialize(format="turtle"))
        settle(served.client)
        yield served.client, data_dir


def post(client: httpx.Client, turtle: str) -> None:
    answer = client.post("/ttl", json={"ttl_content": turtle, "user": "ari"})
    assert answer.status_code == 201, answer.text


def test_rows_are_kept_compressed_and_read_as_they_were_written(server: tuple[httpx.Client, Path]) -> None:
    client, data_dir = server
    reports = views(data_dir)["reports.sqlite3"]
    conversations = [table for table in reports.stored if "conversations" in table and "groups" not in table]
    assert len(conversations) == 1, reports.stored.keys()
    stored, texts = reports.stored[conversations[0]], reports.texts[conversations[0]]
    assert len(stored) >= VISITS
    compressed = [row for row in stored if isinstance(row, bytes)]
    # the first rows, made before the dictionary, stay as text; every later row is compressed
    assert len(compressed) >= len(stored) - SAMPLE_ROWS - 10 > 0
    compressed_bytes = sum(map(len, compressed))
    text_bytes = sum(len(text.encode()) for row, text in zip(stored, texts, strict=True) if isinstance(row, bytes))
    assert compressed_bytes * 3 < text_bytes, (compressed_bytes, text_bytes)
    # the page reads them back: every visit's sentence, once
    rows = client.get("/reports/conversations", params={"limit": 500}).json()["rows"]
    said = sorted(str(row) for row in rows if "this is visit" in str(row))
    assert len(said) == VISITS
    assert all(f"this is visit {index}." in " ".join(said) for index in range(VISITS))


def test_keys_spell_no_namespace_and_pages_keep_the_report_order(server: tuple[httpx.Client, Path]) -> None:
    client, data_dir = server
    robot = client.get("/reports/conversations", params={"limit": 1}).json()["rows"][0]["robot"]
    namespace = robot[: robot.rindex("/") + 1]
    with sqlite3.connect(data_dir / "reports.sqlite3") as connection:
        table = next(row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table' "
                                                          "AND name LIKE '%conversations'"))  # fmt: skip
        keys = [row[0] for row in connection.execute(f"SELECT ord FROM {table}")]
        kept = [row[0] for row in connection.execute(f"SELECT namespaces FROM {KEY_NAMESPACES} WHERE tab = ?",
                                                     (table,))]  # fmt: skip
    assert len(keys) >= VISITS and namespace in kept[0]
    assert not [key for key in keys if namespace in key]
    assert sum(map(len, keys)) / len(keys) < 100  # a robot, a visitor, a time and a message
    whole = client.get("/reports/conversations", params={"limit": 500}).json()["rows"]
    # the robot's rows are a range of the keys: found by the robot's IRI written as the keys write it,
    # page after page in the order of the whole report
    paged: list[dict[str, object]] = []
    after = None
    while True:
        cursor = {"after": after} if after else {}
        page = client.get("/reports/conversations", params={"robot": robot, "limit": 9, **cursor}).json()
        paged += page["rows"]
        after = page.get("next")
        if not after:
            break
    assert paged == [row for row in whole if row["robot"] == robot] and len(paged) >= VISITS
    other = client.get("/reports/conversations", params={"robot": namespace + "robot_other"}).json()["rows"]
    assert other == []


def test_an_erased_visitor_is_in_no_dictionary_and_no_row(server: tuple[httpx.Client, Path]) -> None:
    client, data_dir = server
    needles = [f"this is visit {ERASED}.", f"Visitor {ERASED}"]
    before = views(data_dir)
    quoted = [name for name, view in before.items() for sample in view.samples if needles[0].encode() in sample]
    assert quoted, "the dictionaries are made of the first rows: hers among them"
    visitor = client.get("/reports/participants", params={"limit": 500}).json()["rows"]
    iri = next(str(row["human"]) for row in visitor if str(row.get("human", "")).endswith(f"visitor_{ERASED}"))
    answer = client.post("/humans/erase", json={"iri": iri, "reason": "Request by the data subject"}, timeout=120)
    assert answer.status_code == 200, answer.text
    settle(client)
    after = views(data_dir)
    for name, view in after.items():
        held = [sample for sample in view.samples for needle in needles if needle.encode() in sample]
        assert held == [], name
        rows = [text for texts in view.texts.values() for text in texts for needle in needles if needle in text]
        assert rows == [], name
    # the others are still kept, compressed against dictionaries made again without her
    conversations = after["reports.sqlite3"]
    assert conversations.samples and any(f"this is visit {ERASED + 1}." in text for texts in
                                         conversations.texts.values() for text in texts)  # fmt: skip
