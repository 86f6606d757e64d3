"""The views' CPU bench runs a few posts each way and prints what each view cost (figures are not asserted:
that every view is accounted for, and only the views' run spends on them, is)."""

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
