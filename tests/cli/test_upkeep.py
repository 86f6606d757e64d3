"""`segb upkeep REPORT` tells how a report's rows are kept current: golden outputs for every shipped report, so a
change to a query or to the machinery that keeps it shows up as a difference a reviewer reads."""

from __future__ import annotations

from pathlib import Path

import pytest

from segb_server.backend.cli import main
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "upkeep"
REPORTS = sorted(query.name.removeprefix("reports/") for query in Catalog(PACKAGE_ROOT / "sparql").under("reports"))


@pytest.mark.parametrize("report", REPORTS)
def test_segb_upkeep_tells_how_each_shipped_report_is_kept(report: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["upkeep", report]) == 0
    assert capsys.readouterr().out == (GOLDEN / f"{report}.txt").read_text(encoding="utf-8")


def test_every_shipped_report_has_its_golden_output() -> None:
    assert sorted(path.stem for path in GOLDEN.glob("*.txt")) == REPORTS


def test_a_report_the_plan_cannot_follow_says_why_it_is_evaluated_in_full(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "sparql" / "reports"
    folder.mkdir(parents=True)
    (folder / "paths.rq").write_text(
        "# title: Paths\n# key: ?a\nSELECT ?a ?b WHERE { ?a <urn:x:p>+ ?b }\n", encoding="utf-8"
    )
    assert main(["upkeep", "paths", "--sparql-dir", str(tmp_path / "sparql")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("reports/paths: evaluated in full on every request — ")
    assert "path" in out


def test_an_unknown_report_is_refused_naming_the_reports(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["upkeep", "no-such-report"]) == 2
    error = capsys.readouterr().err
    assert "no report named 'no-such-report'" in error and "conversations" in error


def test_a_timeline_kind_is_told_too_with_what_rules_out_a_new_key(capsys: pytest.CaptureFixture[str]) -> None:
    # The timeline's kinds are kept as the reports are; what tells that a key a batch introduced has no row is
    # printed with them: the only classes a perception may have, the kinds that make an activity another kind's.
    assert main(["upkeep", "timeline/perception"]) == 0
    perception = capsys.readouterr().out
    assert perception.startswith("timeline/perception: kept as rows")
    assert "(?perceptionClass in oro:DetectedHumanEvent, oro:EmotionRecognitionEvent)" in perception
    assert main(["upkeep", "timeline/observation"]) == 0
    observation = capsys.readouterr().out
    assert "what no row may have matches among them (NOT EXISTS): ?observation rdf:type schema:Message ." in observation
