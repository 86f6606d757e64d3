"""People's data and evidence from the command line, on a data directory loaded with the robot client's sample
log: `segb export --human`, `segb erase`, `segb retention`, `segb evidence`, `segb evidence-key` and
`segb verify-evidence`."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.test_cli import segb

pytestmark = pytest.mark.processes  # runs the segb command

BOB = "https://example.org/segb/robots/mirror/v1/human_bob"


def test_a_person_is_exported_then_erased_from_the_command_line(data_dir: Path) -> None:
    page = segb("export", "--data-dir", str(data_dir), "--human", BOB)
    assert page.returncode == 0 and "What the robots' log holds about Bob" in page.stdout
    turtle = segb("export", "--data-dir", str(data_dir), "--human", BOB, "--format", "turtle", "-o",
                  str(data_dir / "bob.ttl"))  # fmt: skip
    assert turtle.returncode == 0 and '"Bob"@en' in (data_dir / "bob.ttl").read_text()

    erased = segb("erase", "--data-dir", str(data_dir), "--human", BOB, "--reason", "request 12", "--by", "dpo")
    assert erased.returncode == 0, erased.stderr
    assert "erased: 88 triples from 1 posts" in erased.stdout  # 86, and 2 texts naming him replaced
    assert "names redacted in 2 texts" in erased.stdout and "note:" not in erased.stdout
    everything = segb("export", "--data-dir", str(data_dir), "--format", "ntriples").stdout
    assert BOB not in everything and '"Bob"@en' not in everything
    assert "Sorry, [erased]. I did not mean" in everything and "Recognise [erased]'s emotion" in everything
    again = segb("export", "--data-dir", str(data_dir), "--human", BOB)
    assert again.returncode == 2 and "holds nothing about" in again.stderr
    missing = segb("erase", "--data-dir", str(data_dir), "--human", BOB, "--reason", "again")
    assert missing.returncode == 2 and "nothing was erased" in missing.stderr


def test_retention_refuses_less_than_six_months_and_erases_what_is_older(data_dir: Path) -> None:
    short = segb("retention", "--data-dir", str(data_dir), "--days", "30")
    assert short.returncode == 2 and "AI Act (Art. 19 and 26(6))" in short.stderr
    assert "ALLOW_SHORT_RETENTION" in short.stderr
    nothing = segb("retention", "--data-dir", str(data_dir), "--days", "200")
    assert nothing.returncode == 0 and "nothing is past retention" in nothing.stdout
    later = segb("retention", "--data-dir", str(data_dir), "--days", "200", "--as-of", "2099-01-01T00:00:00Z")
    assert later.returncode == 0 and "erased 799 triples from 1 posts past retention" in later.stdout
    assert segb("export", "--data-dir", str(data_dir), "--format", "ntriples").stdout == ""


@pytest.mark.parametrize("days", ["3000000", "99999999999"])
def test_a_retention_past_the_calendar_is_refused_in_one_line(data_dir: Path, days: str) -> None:
    refused = segb("retention", "--data-dir", str(data_dir), "--days", days)
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert refused.stderr.startswith("segb: error: invalid setting: retention_days: ") and "36525" in refused.stderr


@pytest.mark.parametrize(
    ("as_of", "said"),
    [("0001-06-01T00:00:00Z", "nothing is past retention"), ("last tuesday", "segb: error: --as-of must be")],
)
def test_retention_as_of_any_time_answers_without_a_traceback(data_dir: Path, as_of: str, said: str) -> None:
    """A time so early that counting back the days leaves the calendar: nothing is older than that."""
    answer = segb("retention", "--data-dir", str(data_dir), "--days", "200", "--as-of", as_of)
    assert "Traceback" not in answer.stderr and said in answer.stdout + answer.stderr


def test_an_evidence_bundle_made_and_checked_from_the_command_line(data_dir: Path) -> None:
    bundle = data_dir / "evidence.zip"
    made = segb("evidence", "--data-dir", str(data_dir), "--since", "2020-01-01T00:00:00Z", "-o", str(bundle))
    assert made.returncode == 0 and " triples, 1 receipts up to entry 1" in made.stdout, made.stderr
    key = segb("evidence-key", "--data-dir", str(data_dir))
    (data_dir / "server.pem").write_text(key.stdout)
    assert "fingerprint (SHA-256)" in key.stderr
    checked = segb("verify-evidence", str(bundle), "--public-key", str(data_dir / "server.pem"))
    assert checked.returncode == 0 and checked.stdout.rstrip().endswith("verified")
    broken = data_dir / "broken.zip"
    broken.write_bytes(bundle.read_bytes()[:-40])
    refused = segb("verify-evidence", str(broken))
    assert refused.returncode == 1 and "not a readable evidence bundle" in refused.stdout
    bad_window = segb("evidence", "--data-dir", str(data_dir), "--since", "yesterday", "-o", str(bundle))
    assert bad_window.returncode == 2 and "since" in bad_window.stderr
