"""The Virtuoso planning bench runs a short history twice and prints, for each history and number of keys, what
one batch of the views' keyed queries cost Virtuoso as new texts and as the same texts again (figures are not
asserted: that every kept view's keyed query was recorded and each row measured, is)."""

from __future__ import annotations

import re

import pytest

from bench.virtuoso_planning import main

pytestmark = [pytest.mark.processes, pytest.mark.virtuoso]  # starts a Virtuoso of its own

ROW = re.compile(r"^\| ([\d,]+) \| (\d+) \| (\d+) \| (\d+) \| (\d+)% \| ([\d.]+) \| (\d+) \| (\d+) \|$", re.MULTILINE)


def test_a_short_run_prints_new_and_planned_texts_for_each_history_and_batch_size(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["--visits", "130", "--more", "260", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    queries = int(re.search(r"each kept view's, (\d+) in all", out).group(1))  # type: ignore[union-attr]
    # the keyed queries of the views a visit has rows in: two reports (conversations, participants), four of the
    # timeline's kinds (messages, listening, responses, shared events), three rules (late answer, reply without a
    # model, unanswered message); the SHACL findings and the graph index bind none, and the kinds a visit's own
    # triples rule out (perceptions, other activities, observations) ask nothing
    assert queries >= 9, out
    rows = ROW.findall(out)
    assert [(history, keys) for history, keys, *_ in rows] == [
        (history, keys) for history in ("130", "260") for keys in ("1", "25", "100")
    ], out
    for *_, new_wall, same_wall in rows:
        assert int(new_wall) > 0 and int(same_wall) > 0, out  # each batch's queries were asked and timed
    assert len(re.findall(r"^- \d+ keys? a query: [\d.]+x Virtuoso's CPU$", out, re.MULTILINE)) == 3, out
