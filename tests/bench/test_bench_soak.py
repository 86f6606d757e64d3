"""The soak runs end to end for a few seconds, views off then on, and prints its figures and their ratios
(figures are not asserted: nothing lost is)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.processes  # runs the bench, which starts servers

ROOT = Path(__file__).resolve().parents[2]


def test_a_short_soak_compares_views_off_and_on_and_loses_nothing() -> None:
    run = subprocess.run(
        [sys.executable, "-m", "bench.soak", "--minutes", "0.1", "--clients", "2", "--compare", "--disk-breakdown"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    out = run.stdout
    assert "views off (KEEP_VIEWS=false)" in out
    assert re.search(r"\| posts/s \| \d+ \| \d+ \| [\d.]+ \| ≥ 0\.8 \|", out), out
    assert len(re.findall(r"\| lost \(triples acknowledged, not stored\) \| 0 of [\d,]+ \| 0 \|", out)) == 2, out
    assert "timeline.sqlite3" in out  # every view's file is counted on disk
    # Where the views' bytes are: each file's biggest tables, and the conversations' rows as stored: past their
    # table's first rows (its dictionary's sample), compressed, a few dozen bytes each.
    assert re.search(r"## reports\.sqlite3: [\d.]+ MiB", out), out
    kept = re.search(r"\| report_reports_conversations \| [\d,]+ \| (\d+) \| (\d+)% \|", out)
    assert kept, out
    assert int(kept[1]) < 100 and int(kept[2]) >= 80, kept[0]
    assert re.search(r"\| RSS at [\d,]+ posts MiB \| (\d+|not reached) \| \d+ \| [\d.]+ \| ≤ 1\.2 \|", out), out


@pytest.mark.virtuoso
def test_a_short_soak_on_virtuoso_runs_the_compose_default_of_two_workers_and_loses_nothing(tmp_path: Path) -> None:
    log = tmp_path / "server.log"
    run = subprocess.run(
        [sys.executable, "-m", "bench.soak", "--store", "virtuoso", "--minutes", "0.1", "--clients", "2",
         "--server-log", str(log), "--server-log-level", "INFO"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    out = run.stdout
    assert "2 API workers" in out and "≥ 100 posts/s" in out and "p99 ≤ 5 s" in out, out
    assert re.search(r"\| lost \(triples acknowledged, not stored\) \| 0 of [\d,]+ \| 0 \|", out), out
    assert "SEGB API ready (store=virtuoso" in log.read_text()  # the server's own log was kept


def test_memory_at_a_number_of_posts_is_read_between_the_samples_around_it() -> None:
    from bench.soak import rss_when

    samples = [(0, 100.0), (1000, 200.0), (3000, 400.0)]
    assert rss_when(samples, 2000) == 300.0
    assert rss_when(samples, 1000) == 200.0
    assert rss_when(samples, 5000) is None  # the run never got there


def test_the_servers_cpu_a_post_is_told_for_the_runs_first_and_last_thirds() -> None:
    from bench.soak import Posting, Samples, SoakFigures, ms_a_post

    assert ms_a_post([(0, 10.0), (1000, 15.0)]) == 5.0  # 5 CPU seconds over 1,000 posts
    assert ms_a_post([(1000, 15.0), (1000, 16.0)]) is None  # no post between them
    # Six samples: the first third 1,000 posts for 5 s of CPU, the last 1,000 posts for 8 s.
    cpu = [(0, 0.0), (500, 2.5), (1000, 5.0), (2000, 11.0), (2500, 15.0), (3000, 19.0)]
    figures = SoakFigures("oxigraph", 1, 4, True, 1, Posting(acknowledged=3000, seconds=60), Samples(cpu_by_posts=cpu),
                          0.1, 10, 10, {"store": 1.0})  # fmt: skip
    assert "| server CPU ms a post (its processes'), first / last third of the run | 5.0 / 8.0 (1.60x) | |" in (
        figures.markdown()
    )
    assert (
        "server CPU ms a post"
        not in SoakFigures(
            "oxigraph", 1, 4, True, 1, Posting(), Samples(cpu_by_posts=cpu[:2]), 0.1, 10, 10, {"store": 1.0}
        ).markdown()
    )  # too few samples to tell
