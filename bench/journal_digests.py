"""What the journal's set of triple digests costs a post at a long history, and what a tiered set would save.

The journal keeps every triple's digest (16 random bytes) in one B-tree (`journal_triples`), so that a re-sent
triple is recognised; each new digest lands on a page of its own once the table is large. A tiered set would
insert into a small table of recent digests (after looking each up in the large one) and merge it into the large
one in sorted runs. This bench times both layouts on SQLite files set up as the journal's (WAL, synchronous
NORMAL, secure_delete: `SqliteDatabase`), each holding `--history` digests first, then committing `--commits`
posts of `--per-post` new digests each; the two layouts in turns, `--rounds` times.

    python -m bench.journal_digests                       # 4,000,000 digests, 3,000 posts of 57
    python -m bench.journal_digests --history 8000000 --merge-at 200000

It changes nothing in the project: it measures a layout before one is built.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from bench.measure import percentile
from bench.tables import table
from segb_server.backend.state.sqlite import SqliteDatabase

LARGE = "CREATE TABLE IF NOT EXISTS digests (digest BLOB PRIMARY KEY) WITHOUT ROWID"
RECENT = "CREATE TABLE IF NOT EXISTS recent (digest BLOB PRIMARY KEY) WITHOUT ROWID"
FILL_CHUNK = 100_000
FILL_STATEMENT = 5_000  # rows an INSERT's VALUES list holds (SQLite allows 32,766 parameters)

Layout = Callable[[SqliteDatabase, list[bytes]], int]


def one_table(database: SqliteDatabase, digests: list[bytes]) -> int:
    """The journal's layout: insert, the table telling which were new."""
    marks = ", ".join(["(?)"] * len(digests))
    sql = f"INSERT INTO digests (digest) VALUES {marks} ON CONFLICT (digest) DO NOTHING RETURNING digest"
    return len(database.execute(sql, digests).fetchall())


def tiered(merge_at: int) -> Layout:
    """Recent digests apart, merged into the large table in one sorted run every `merge_at` new ones."""
    pending = [0]

    def insert(database: SqliteDatabase, digests: list[bytes]) -> int:
        marks = ", ".join(["?"] * len(digests))
        known = {row[0] for row in database.execute(f"SELECT digest FROM digests WHERE digest IN ({marks})", digests)}
        fresh = [digest for digest in digests if digest not in known]
        if not fresh:
            return 0
        values = ", ".join(["(?)"] * len(fresh))
        sql = f"INSERT INTO recent (digest) VALUES {values} ON CONFLICT (digest) DO NOTHING RETURNING digest"
        new = len(database.execute(sql, fresh).fetchall())
        pending[0] += new
        if pending[0] >= merge_at:
            database.execute("INSERT INTO digests SELECT digest FROM recent ORDER BY digest ON CONFLICT DO NOTHING")
            database.execute("DELETE FROM recent")
            pending[0] = 0
        return new

    return insert


def written_bytes() -> int:
    for line in Path("/proc/self/io").read_text().splitlines():
        if line.startswith("write_bytes:"):
            return int(line.split()[1])
    return 0


def run(layout: Layout, history: int, commits: int, per_post: int) -> tuple[list[float], float]:
    """CPU ms of each post's commit, and KiB written to disk a post, at `history` digests."""
    directory = Path(tempfile.mkdtemp(prefix="segb-bench-digests-"))
    database = SqliteDatabase(directory / "journal.sqlite3")
    try:
        database.execute(LARGE)
        database.execute(RECENT)
        for start in range(0, history, FILL_CHUNK):  # sorted runs: a history as compact as the journal's
            chunk = sorted(os.urandom(16) for _ in range(min(FILL_CHUNK, history - start)))
            database.execute("BEGIN")
            for at in range(0, len(chunk), FILL_STATEMENT):
                part = chunk[at : at + FILL_STATEMENT]
                database.execute(f"INSERT INTO digests VALUES {', '.join(['(?)'] * len(part))}", part)
            database.execute("COMMIT")
        database.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        times = []
        before = written_bytes()
        for _ in range(commits):
            digests = [os.urandom(16) for _ in range(per_post)]
            started = time.process_time()
            database.execute("BEGIN IMMEDIATE")
            layout(database, digests)
            database.execute("COMMIT")
            times.append((time.process_time() - started) * 1000)
        return times, (written_bytes() - before) / 1024 / commits
    finally:
        database.close()
        shutil.rmtree(directory, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--history", type=int, default=4_000_000, help="digests in the set before the posts")
    parser.add_argument("--commits", type=int, default=3_000, help="posts committed, one transaction each")
    parser.add_argument("--per-post", type=int, default=57, help="new digests a post (the soak's visit: 57)")
    parser.add_argument("--merge-at", type=int, default=50_000, help="the tiered set's recent digests merged at")
    parser.add_argument("--rounds", type=int, default=2, help="each layout this many times, in turns")
    args = parser.parse_args()
    layouts: dict[str, Layout] = {"one table (the journal's)": one_table, "tiered": tiered(args.merge_at)}
    results: dict[str, list[tuple[list[float], float]]] = {name: [] for name in layouts}
    for _ in range(args.rounds):
        for name, layout in layouts.items():
            results[name].append(run(layout, args.history, args.commits, args.per_post))
    print(
        f"{args.commits:,} posts of {args.per_post} new digests at a history of {args.history:,}; "
        f"tiered merged every {args.merge_at:,}; {args.rounds} round(s) each, in turns"
    )
    rows = []
    baseline = None
    for name, runs in results.items():
        times = [value for run_times, _ in runs for value in run_times]
        mean = sum(times) / len(times)
        baseline = baseline or mean
        written = sum(kib for _, kib in runs) / len(runs)
        rows.append([name, f"{mean:.3f}", f"{percentile(times, 50):.3f}", f"{percentile(times, 95):.3f}",
                     f"{percentile(times, 99):.3f}", f"{written:.0f}", f"{mean / baseline:.2f}"])  # fmt: skip
    header = ["layout", "CPU ms a post (mean)", "p50", "p95", "p99", "KiB written a post", "mean ÷ one table"]
    print("\n".join(table(header, rows)))


if __name__ == "__main__":
    main()
