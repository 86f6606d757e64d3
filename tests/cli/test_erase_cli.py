"""`segb erase` on a data directory loaded with the robot client's sample log: `--dry-run IRI` counts what would go
by kind and writes nothing; a class, a robot or an IRI the log does not type as a person is refused in one line."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from tests.cli.test_cli import segb
from tests.cli.test_people_cli import BOB

pytestmark = pytest.mark.processes  # runs the segb command


def receipts(data_dir: Path) -> list[tuple[object, ...]]:
    with sqlite3.connect(data_dir / "journal.sqlite3") as journal:
        return journal.execute("SELECT sequence, receipt_hash, content FROM receipts ORDER BY sequence").fetchall()


def test_a_dry_run_counts_what_would_go_and_writes_nothing(data_dir: Path) -> None:
    store_before, journal_before = (
        segb("export", "--data-dir", str(data_dir), "--format", "ntriples").stdout,
        receipts(data_dir),
    )
    dry = segb("erase", "--data-dir", str(data_dir), "--dry-run", BOB)
    assert dry.returncode == 0, dry.stderr
    assert dry.stdout.startswith("dry run: would erase ") and "human 1" in dry.stdout and "message " in dry.stdout
    assert "nothing was written" in dry.stdout
    assert segb("export", "--data-dir", str(data_dir), "--format", "ntriples").stdout == store_before
    assert receipts(data_dir) == journal_before
    # The erasure then takes what the dry run counted.
    resources = int(dry.stdout.split("would erase ", 1)[1].split(" ", 1)[0])
    erased = segb("erase", "--data-dir", str(data_dir), BOB, "--reason", "request 12")
    assert erased.returncode == 0 and f"({resources} resources)" in erased.stdout, erased.stdout + erased.stderr


@pytest.mark.parametrize(
    ("iri", "said"),
    [
        ("http://kb.openrobots.org#Human", "is a class or a predicate the log uses"),
        ("https://example.org/segb/robots/mirror/v1/robot_mirror1", "is not a person: the log types"),
        ("http://schema.org/sender", "is a class or a predicate the log uses"),
    ],
)
def test_what_is_not_a_person_is_refused_in_one_line(data_dir: Path, iri: str, said: str) -> None:
    journal_before = receipts(data_dir)
    for dry_run in ((), ("--dry-run",)):
        refused = segb("erase", "--data-dir", str(data_dir), *dry_run, "--human", iri, "--reason", "a mistake")
        assert refused.returncode == 2 and said in refused.stderr, refused.stderr
        assert refused.stderr.startswith("segb: error: ") and refused.stderr.count("\n") == 1
    assert receipts(data_dir) == journal_before


def test_an_erasure_needs_one_iri_and_a_reason(data_dir: Path) -> None:
    for args in ((BOB,), (BOB, "--human", BOB, "--reason", "x"), ("--reason", "x")):
        refused = segb("erase", "--data-dir", str(data_dir), *args)
        assert refused.returncode == 2 and refused.stderr.startswith("segb: error: give the person's IRI once")
