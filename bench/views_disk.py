"""Where the views' files spend their bytes: each view database's biggest tables and indexes, its free pages, its
kept rows' mean size as stored and how many are stored compressed, and what those kept as text would take
compressed with a dictionary of their own (zlib's preset dictionary, from the table's first rows).

    python -m bench.views_disk DATA_DIR          # a server's data directory (stopped, or at rest)
    python -m bench.views_disk DATA_DIR --top 20

Reads the files only (SQLite's `dbstat`, opened read-only). It measures where a compact layout of the views
would save room; it changes nothing.
"""

from __future__ import annotations

import argparse
import sqlite3
import zlib
from pathlib import Path

from bench.tables import table
from segb_server.backend.services.container import VIEW_FILES

DICTIONARY_ROWS = 200  # the rows a table's dictionary is made of
SAMPLED_ROWS = 5_000  # the rows compressed with it
DICTIONARY_BYTES = 32 * 1024  # zlib's window: a preset dictionary past it is not used


def objects(database: sqlite3.Connection, top: int) -> list[tuple[str, float, int]]:
    """The `top` biggest tables and indexes: name, MiB, cells."""
    return database.execute(
        "SELECT name, SUM(pgsize) / 1048576.0, SUM(ncell) FROM dbstat GROUP BY name ORDER BY 2 DESC LIMIT ?", (top,)
    ).fetchall()


def row_tables(database: sqlite3.Connection) -> list[str]:
    """The tables that keep a report's rows (a `row` column of JSON)."""
    names = [name for (name,) in database.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
    return [name for name in names if "row" in {column[1] for column in database.execute(f"PRAGMA table_info({name})")}]


def kept(database: sqlite3.Connection, name: str) -> tuple[int, float, float]:
    """Rows of `name`, their mean size as stored, and the share of them stored compressed (`row_codec.py`)."""
    count, mean, packed = database.execute(
        f"SELECT COUNT(*), COALESCE(AVG(LENGTH(CAST(row AS BLOB))), 0), COALESCE(AVG(typeof(row) = 'blob'), 0) "
        f"FROM {name}"
    ).fetchone()
    return count, mean, packed


def compressed(database: sqlite3.Connection, name: str) -> tuple[float, float] | None:
    """The mean size of the rows of `name` kept as text, and their mean size compressed with a dictionary of
    the first of them (None when too few are kept as text to tell)."""
    rows = [text.encode() for (text,) in database.execute(f"SELECT row FROM {name} WHERE typeof(row) = 'text' "
                                                          "LIMIT ?", (DICTIONARY_ROWS + SAMPLED_ROWS,))]  # fmt: skip
    if len(rows) <= DICTIONARY_ROWS:
        return None
    dictionary = b"".join(rows[:DICTIONARY_ROWS])[-DICTIONARY_BYTES:]
    sampled = rows[DICTIONARY_ROWS:]
    packed = 0
    for row in sampled:
        compressor = zlib.compressobj(9, zdict=dictionary)
        packed += len(compressor.compress(row) + compressor.flush())
    return sum(map(len, sampled)) / len(sampled), packed / len(sampled)


def report(data_dir: Path, top: int) -> list[str]:
    lines: list[str] = []
    for file_name in VIEW_FILES:
        path = data_dir / file_name
        if not path.exists():
            continue
        database = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            size = path.stat().st_size / 2**20
            lines += [f"## {file_name}: {size:.1f} MiB", ""]
            biggest = [[name, f"{mib:.1f}", f"{cells:,}"] for name, mib, cells in objects(database, top)]
            lines += table(["table or index", "MiB", "cells"], biggest)
            free = (
                database.execute("PRAGMA freelist_count").fetchone()[0]
                * database.execute("PRAGMA page_size").fetchone()[0]
            )
            lines += [f"free pages: {free / 2**20:.1f} MiB", ""]
            names = row_tables(database)
            if names:
                lines += table(
                    ["rows of", "rows", "mean row B as stored", "stored compressed", "as text, compressed B"],
                    [[name, f"{count:,}", f"{mean:.0f}", f"{share:.0%}", _estimate(compressed(database, name))]
                     for name in names for count, mean, share in [kept(database, name)]],
                )  # fmt: skip
        finally:
            database.close()
    return lines


def _estimate(found: tuple[float, float] | None) -> str:
    return "" if found is None else f"{found[0]:.0f} → {found[1]:.0f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("data_dir", type=Path, help="a server's data directory")
    parser.add_argument("--top", type=int, default=12, help="tables and indexes listed per file")
    arguments = parser.parse_args()
    print("\n".join(report(arguments.data_dir, arguments.top)))


if __name__ == "__main__":
    main()
