"""The views' CPU bench runs a few posts each way and prints what each view cost (figures are not asserted:
that every view is accounted for, and only the views' run spends on them, is); against Virtuoso, Virtuoso's CPU
a post too."""

from __future__ import annotations

import re

import pytest

from bench.views_cpu import main


def test_a_short_run_prints_each_views_cpu_per_post_and_the_ratio_to_views_off(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["--posts", "40", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"\| posts/s \| \d+ \| \d+ \| [\d.]+ \|", out), out
    assert re.search(r"\| of which the views' updates \(their threads' CPU\) \| [\d.]+ \| 0 \| \|", out), out
    rows = dict(re.findall(r"^\| ([a-z-]+(?:/[a-z-]+)?) \| ([\d.]+) \| [\d.]+ \| [\d.]+% \|$", out, re.MULTILINE))
    for view in ("reports/conversations", "graph", "shape-findings", "timeline/message", "rules/late-answer"):
        assert float(rows[view]) > 0, out  # each kept view's updates were timed
    shares = [float(share) for share in re.findall(r"\| ([\d.]+)% \|$", out, re.MULTILINE)]
    assert sum(shares) == pytest.approx(100, abs=1), out


@pytest.mark.processes
@pytest.mark.virtuoso
def test_against_virtuoso_the_run_also_prints_virtuosos_cpu_per_post(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--posts", "40", "--rounds", "1", "--store", "virtuoso"]) == 0
    out = capsys.readouterr().out
    assert "--store virtuoso" in out, out
    found = re.search(r"\| Virtuoso's CPU ms / post \| ([\d.]+) \| ([\d.]+) \| [\d.]+ \|", out)
    assert found, out
    assert float(found.group(1)) > 0, out  # read from Virtuoso's process: its writes and the views' queries
    assert re.search(r"\| most posts/s \d+ cores could answer, Virtuoso's CPU included \| \d+ \| \d+ \| \|", out), out
    rows = dict(re.findall(r"^\| ([a-z-]+(?:/[a-z-]+)?) \| ([\d.]+) \| [\d.]+ \| [\d.]+% \|$", out, re.MULTILINE))
    assert float(rows["reports/conversations"]) > 0, out
