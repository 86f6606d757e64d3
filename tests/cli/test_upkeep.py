"""`segb upkeep REPORT` tells how a report's rows are kept current: golden outputs for every shipped report, so a
change to a query or to the machinery that keeps it shows up as a difference a reviewer reads."""

from __future__ import annotations

from pathlib import Path

import pytest
from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.cli import main
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.store.factory import open_store
from tests.conftest import make_settings

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "upkeep"
CORPUS = Path(__file__).resolve().parents[1] / "fixtures" / "reading"
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


def test_an_unknown_view_is_refused_naming_the_views(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["upkeep", "no-such-report"]) == 2
    error = capsys.readouterr().err
    assert "no kept view named 'no-such-report'" in error and "conversations" in error


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


def test_every_kept_view_is_told_the_rules_and_the_graph_index_too(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["upkeep"]) == 0
    told = capsys.readouterr().out
    for view in ("reports/conversations: kept", "timeline/message: kept", "rules/unanswered-message: kept"):
        assert view in told
    assert "graph index:" in told and "SHACL rules' findings" in told


def publish_corpus(data: Path) -> None:
    assert main(["import", "--data-dir", str(data), str(CORPUS / "own-turtle.ttl")]) == 0


def test_diff_finds_the_kept_rows_equal_to_the_query_in_full(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    publish_corpus(tmp_path / "data")
    capsys.readouterr()
    assert main(["upkeep", "--data-dir", str(tmp_path / "data"), "--diff", "conversations"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "reports/conversations: 3 rows kept, 3 evaluated in full (rows keyed by ?message)",
        "  the same rows: if one is wrong, the query is (its .rq file, or a rule of reading it uses)",
    ]
    question = "https://example.org/greeter/question_1"
    assert main(["upkeep", "--data-dir", str(tmp_path / "data"), "--diff", "rules/unanswered-message", question]) == 0
    assert capsys.readouterr().out.startswith("rules/unanswered-message: 1 rows kept, 1 evaluated in full")


def test_diff_tells_a_row_the_upkeep_never_saw(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A triple written into the store behind the journal's back (as a bug in the upkeep would leave the rows): the
    full evaluation has a row the kept view lacks, and the command says so with exit code 1."""
    data = tmp_path / "data"
    publish_corpus(data)
    greeter = "https://example.org/greeter/"
    assert main(["upkeep", "--data-dir", str(data), "--diff", "timeline/message", greeter + "question_1"]) == 0
    store = open_store(make_settings(data_dir=data, store="oxigraph"))
    try:
        hidden = Quad(NamedNode(greeter + "question_1"), NamedNode("http://schema.org/text"), Literal("Hidden?"))
        store.apply([hidden], through=store.applied_through() or 0)
    finally:
        store.close()
    capsys.readouterr()
    assert main(["upkeep", "--data-dir", str(data), "--diff", "timeline/message", greeter + "question_1"]) == 1
    out = capsys.readouterr().out
    assert "they differ: the upkeep missed a change" in out
    assert "only in full:" in out and "Hidden?" in out and "only kept:" not in out


def test_diff_of_one_view_needs_its_name(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["upkeep", "--diff"]) == 2
    assert "--diff compares one view" in capsys.readouterr().err
