"""The `segb` command, run as a real process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from pyoxigraph import RdfFormat

from segb_server.backend.serving import listens_beyond_this_machine
from tests.conftest import FIXTURES
from tests.support.graphs import value_triples
from tests.support.net import free_port

pytestmark = pytest.mark.processes  # runs the segb command

SEGB = [sys.executable, "-m", "segb_server.backend.cli"]  # the `segb` command of this interpreter


def segb(*args: str, env: dict[str, str] | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*SEGB, *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=clean_env(env),
        cwd=cwd,
    )


def clean_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    env = {key: value for key, value in os.environ.items() if not key.startswith(("SECRET_KEY", "STORE", "API_"))}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2])
    env.update(extra or {})
    return env


def test_import_then_export_round_trips_the_fixtures(tmp_path: Path) -> None:
    files = [FIXTURES / "sample_two_robots.ttl", FIXTURES / "reference_uc02.ttl"]
    loaded = segb("import", "--data-dir", str(tmp_path), *map(str, files))
    assert loaded.returncode == 0, loaded.stderr
    assert "sample_two_robots.ttl: 799 triples read, 799 new" in loaded.stdout
    assert "reference_uc02.ttl: 627 triples read" in loaded.stdout

    again = segb("import", "--data-dir", str(tmp_path), str(files[0]))
    assert "799 triples read, 0 new" in again.stdout

    out = tmp_path / "out.nt"
    exported = segb("export", "--data-dir", str(tmp_path), "--format", "ntriples", "--output", str(out))
    assert exported.returncode == 0, exported.stderr
    expected = set().union(*(value_triples(path.read_bytes(), RdfFormat.TURTLE) for path in files))
    assert value_triples(out.read_bytes()) == expected


def test_import_reports_bad_files_clearly(tmp_path: Path) -> None:
    broken = tmp_path / "broken.ttl"
    broken.write_text("@prefix ex: <https://ex.org/> .\nex:a ex:b .\n")
    missing = segb("import", "--data-dir", str(tmp_path), str(tmp_path / "nope.ttl"))
    invalid = segb("import", "--data-dir", str(tmp_path / "db"), str(broken))
    assert (missing.returncode, "no such file" in missing.stderr) == (2, True)
    assert invalid.returncode == 2
    assert "Invalid Turtle at line 2" in invalid.stderr
    exported = tmp_path / "graph.jsonld"
    exported.write_text("{}")
    unread = segb("import", "--data-dir", str(tmp_path / "db"), str(exported))
    assert unread.returncode == 2 and unread.stderr.splitlines() == [
        "segb: error: graph.jsonld: segb import reads Turtle (.ttl, .turtle) or N-Triples (.nt, .ntriples) files"
    ]  # one line, before any progress bar


def test_an_export_in_n_triples_imports_again_whatever_its_suffix(tmp_path: Path) -> None:
    loaded = segb("import", "--data-dir", str(tmp_path / "one"), str(FIXTURES / "sample_two_robots.ttl"))
    assert loaded.returncode == 0, loaded.stderr
    out = tmp_path / "all.ntriples"
    assert segb("export", "--data-dir", str(tmp_path / "one"), "--format", "ntriples", "-o", str(out)).returncode == 0
    again = segb("import", "--data-dir", str(tmp_path / "two"), str(out))
    assert again.returncode == 0 and "all.ntriples: 799 triples read, 799 new" in again.stdout, again.stderr


def test_serve_runs_api_and_ui_and_stops_on_sigterm(tmp_path: Path) -> None:
    api_port, ui_port = free_port(), free_port()
    process = subprocess.Popen(
        [*SEGB, "serve", "--data-dir", str(tmp_path)],
        env=clean_env({"API_PORT": str(api_port), "UI_PORT": str(ui_port)}),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        ready = wait_for(f"http://127.0.0.1:{api_port}/healthz/ready")
        assert ready.json() == {"ready": True, "oxigraph": True}
        page = wait_for(f"http://127.0.0.1:{ui_port}/health")
        assert "Ready" in page.text
        assert "Content-Security-Policy" in page.headers
    finally:
        process.send_signal(signal.SIGTERM)
        output, _ = process.communicate(timeout=30)
    assert process.returncode == 0, output
    assert (tmp_path / "oxigraph").is_dir()
    assert "AUTHENTICATION IS OFF" not in output  # on 127.0.0.1 only, the default


@pytest.mark.parametrize(
    ("host", "beyond"),
    [("127.0.0.1", False), ("127.0.0.2", False), ("::1", False), ("localhost", False),
     ("0.0.0.0", True), ("::", True), ("192.0.2.7", True), ("robots.example", True)],
)  # fmt: skip
def test_only_loopback_hosts_keep_the_server_to_this_machine(host: str, beyond: bool) -> None:
    assert listens_beyond_this_machine(host) is beyond


def test_serve_without_auth_on_every_interface_warns_loudly(tmp_path: Path) -> None:
    port = free_port()
    process = subprocess.Popen(
        [*SEGB, "serve", "--only", "api", "--store", "memory", "--host", "0.0.0.0", "--api-port", str(port)],
        env=clean_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert wait_for(f"http://127.0.0.1:{port}/healthz/ready").status_code == 200
    finally:
        process.send_signal(signal.SIGTERM)
        output, _ = process.communicate(timeout=30)
    [warning] = [line for line in output.splitlines() if "AUTHENTICATION IS OFF" in line]
    assert "WARNING segb.serve: AUTHENTICATION IS OFF (SECRET_KEY is empty) and the API listens on 0.0.0.0" in warning
    assert f"anyone who can reach port {port} can publish, read and delete every log" in warning
    assert "Set SECRET_KEY" in warning and "PUBLISH_ADDRESS" in warning


def test_serve_says_how_to_make_an_unwritable_data_dir_writable(tmp_path: Path) -> None:
    """A folder the server's user cannot write (a root-owned host folder on a container's /data): one line
    saying which folder, which user and the command that fixes it, and no traceback."""
    data = tmp_path / "data"
    data.mkdir()
    data.chmod(0o555)
    # As root, without the capability that lets root write anywhere, as the image's user would be refused.
    unprivileged = ["setpriv", "--bounding-set=-dac_override,-dac_read_search"] if os.geteuid() == 0 else []
    result = subprocess.run(
        [*unprivileged, *SEGB, "serve", "--only", "api", "--data-dir", str(data)],
        capture_output=True,
        text=True,
        timeout=120,
        env=clean_env(),
    )
    assert result.returncode == 2, result.stderr
    uid, gid = os.geteuid(), os.getegid()
    assert result.stderr.splitlines() == [
        f"segb: error: DATA_DIR {data} is not writable by this server's user, uid {uid} (Permission denied: "
        f"{data / 'logs'}): give the folder to that user: `sudo chown -R {uid}:{gid} {data}` (for a host folder "
        f"mounted on {data} in a container, run it on the host folder)"
    ]


def test_flags_override_environment_and_bad_settings_fail_fast(tmp_path: Path) -> None:
    weak = segb("serve", "--data-dir", str(tmp_path), env={"SECRET_KEY": "short"})
    assert weak.returncode == 2
    assert "SECRET_KEY must be at least 32 characters" in weak.stderr

    port = free_port()
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "segb_server.backend.cli",
            "serve",
            "--only",
            "api",
            "--store",
            "memory",
            "--api-port",
            str(port),
        ],
        env=clean_env({"API_PORT": "1", "STORE": "virtuoso"}),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        assert wait_for(f"http://127.0.0.1:{port}/healthz/ready").json() == {"ready": True, "memory": True}
    finally:
        process.terminate()
        process.wait(timeout=30)


# A server's start on a busy two-core machine (another test run, a CI neighbour) parses every kept query and
# starts its processes: a minute and more. The wait ends as soon as it answers, so a generous limit costs nothing
# when all is well.
START_SECONDS = 180


def wait_for(url: str, timeout: float = START_SECONDS) -> httpx.Response:
    """The first answer from `url`, asked again until it comes or `timeout` seconds passed."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return httpx.get(url, timeout=2)
        except httpx.HTTPError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def test_check_prints_each_finding_with_its_line_and_fails_on_violations(tmp_path: Path) -> None:
    from tests.support.rule_scenarios import troubled

    scenario, expected = troubled()
    scenario.run_steps()
    log = tmp_path / "ari.ttl"
    log.write_text(scenario.published_turtle()[0], encoding="utf-8")
    result = subprocess.run([*SEGB, "check", str(log)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1, result.stderr
    printed = result.stdout.splitlines()
    assert printed[-1].endswith("3 violations, 6 warnings, 2 infos")
    assert any(line.startswith(f"{log}:") and ": violation: [time-not-datetime]" in line for line in printed)
    assert len(printed) - 1 == sum(len(nodes) for nodes in expected.values())
    as_json = json.loads(subprocess.run([*SEGB, "check", str(log), "--format", "json"], capture_output=True, text=True,
                                        timeout=120).stdout)  # fmt: skip
    assert as_json["violations"] == 3 and all(found["line"] for found in as_json["findings"])
    junit = subprocess.run([*SEGB, "check", str(log), "--format", "junit"], capture_output=True, text=True, timeout=120)
    assert '<testsuite name="segb check' in junit.stdout and 'failures="3"' in junit.stdout


def test_check_names_the_human_a_reply_without_the_model_answers(tmp_path: Path) -> None:
    """The example robot's log as it publishes it: its four fallback replies each answer Maria."""
    from segb_server.examples.emotion_mirror.driver import play
    from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
    from segb_server.examples.emotion_mirror.script import default_script

    mission = EmotionMirrorMission.start(RobotConfig(), human_id="maria", human_name="Maria")
    replies = [step.iri for step in play(mission, default_script()) if step.kind == "reply"]
    log = tmp_path / "mirror.ttl"
    log.write_text(mission.logger.graph.serialize(format="turtle"), encoding="utf-8")
    result = segb("check", str(log), "--format", "json")
    assert result.returncode == 0, result.stderr
    found = [f for f in json.loads(result.stdout)["findings"] if f["rule"] == "reply-without-model"]
    assert sorted(f["focus"] for f in found) == sorted(map(str, replies)) and len(found) == 4
    assert {f["human"] for f in found} == {str(mission.human)}
    assert all(f["message"].startswith("Emotion Mirror replied without using any model to Maria: ") for f in found)


def test_check_passes_a_clean_log_and_takes_a_folder_of_rules(tmp_path: Path) -> None:
    clean = tmp_path / "clean.ttl"
    clean.write_text('<https://example.org/r> a <http://kb.openrobots.org#Robot> ; <http://schema.org/name> "R" .\n')
    result = subprocess.run([*SEGB, "check", str(clean)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stdout.strip().endswith("0 violations, 0 warnings, 0 infos")
    rules = tmp_path / "rules"
    rules.mkdir()
    (rules / "robot-named-r.rq").write_text(
        "# id: robot-named-r\n# title: A robot named R\n# severity: violation\n# key: ?focus\n"
        'SELECT ?time ?focus ?message WHERE { ?focus <http://schema.org/name> "R" . BIND ("named R" AS ?message) }\n'
        "ORDER BY ?time ?focus\n"
    )
    flagged = subprocess.run([*SEGB, "check", str(clean), "--rules", str(rules)], capture_output=True, text=True,
                             timeout=120)  # fmt: skip
    assert flagged.returncode == 1
    assert f"{clean}:1: violation: [robot-named-r] named R <https://example.org/r>" in flagged.stdout
    missing = subprocess.run([*SEGB, "check", str(tmp_path / "nope.ttl")], capture_output=True, text=True, timeout=60)
    assert missing.returncode != 0 and "no such file" in missing.stderr
