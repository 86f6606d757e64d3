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
from segb_server.backend.services.views.kept_queries.facets import FACETS_PREFIX
from segb_server.backend.services.views.kept_queries.key_namespaces import KEY_NAMESPACES
from segb_server.backend.services.views.kept_queries.row_codec import DICTIONARIES, SAMPLE_ROWS, RowCodec
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


def test_the_timeline_kinds_keep_a_facet_s_pairs_once_and_filter_by_them(server: tuple[httpx.Client, Path]) -> None:
    """The timeline's kinds of activity have the same facet (the people an activity involved): its pairs are kept
    in one table, not once a kind, and every kind's rows are still filtered by it."""
    client, data_dir = server
    with sqlite3.connect(data_dir / "timeline.sqlite3") as connection:
        names = [row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        pairs = {name: connection.execute(f"SELECT COUNT(*) FROM {name}").fetchone()[0]
                 for name in names if name.startswith(FACETS_PREFIX)}  # fmt: skip
    assert not [name for name in names if name.endswith("_facets")]  # no kind keeps pairs of its own
    assert 1 <= len(pairs) <= 3 and any(pairs.values()), pairs
    robot = client.get("/reports/conversations", params={"limit": 1}).json()["rows"][0]["robot"]
    everything = client.get("/timeline", params={"robot": robot, "limit": 5000}).json()["rows"]
    visitor = next(human for row in everything for human in row["humans"] if human.endswith("_5"))
    filtered = client.get("/timeline", params={"robot": robot, "human": visitor, "limit": 500}).json()["rows"]
    assert {"listening", "response", "message"} <= {row["kind"] for row in filtered}
    # her visit's events, those her rows name and the activities that involved her, and no other visit's
    ids = {row["id"] for row in filtered}
    assert {row["id"] for row in everything if visitor in row["humans"]} <= ids <= {row["id"] for row in everything}
    assert all("_5 " in event for event in ids if not event.startswith("shared-event")), ids
    assert len([event for event in ids if event.startswith("shared-event")]) == 1  # what she said, heard once
    assert [row["time"] for row in filtered] == sorted(row["time"] for row in filtered)


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
