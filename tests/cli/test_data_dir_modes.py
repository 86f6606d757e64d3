"""What `segb serve` and the other commands write in DATA_DIR holds people's data (the journal, the SQLite state,
the views, the embedded store, logs, the evidence key), and so do the exports they write: only the server's user may
read them. Every file the commands create is 600 and every folder 700, whatever the umask they were started with."""

from __future__ import annotations

import os
import stat
import subprocess
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.cli.test_cli import SEGB, clean_env
from tests.support.net import free_port
from tests.support.processes import running
from tests.support.settle import settle

pytestmark = pytest.mark.processes

SAID = """
@prefix schema: <http://schema.org/> . @prefix prov: <http://www.w3.org/ns/prov#> .
@prefix segb: <http://www.gsi.upm.es/ontologies/segb/ns#> . @prefix oro: <http://kb.openrobots.org#> .
@prefix foaf: <http://xmlns.com/foaf/0.1/> . @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
<https://e.org/robot> a oro:Robot ; schema:name "ARI" .
<https://e.org/ines> a oro:Human ; foaf:firstName "Inés" .
<https://e.org/listen> a segb:LoggedActivity, oro:ListeningEvent ; segb:wasPerformedBy <https://e.org/robot> ;
    prov:startedAtTime "2026-05-02T10:00:00Z"^^xsd:dateTime .
<https://e.org/heard> a schema:Message, oro:InitialMessage ; schema:sender <https://e.org/ines> ;
    schema:text "My room number is 12" ; prov:wasGeneratedBy <https://e.org/listen> .
"""


@pytest.fixture
def permissive_umask() -> Iterator[None]:
    """The commands start from the common 022 (files 644, folders 755): their own setting is what is checked."""
    before = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(before)


def modes(folder: Path) -> dict[str, str]:
    """Every path under `folder` (itself included) → its permission bits as octal, a folder's ending in `/`."""
    found = {}
    for path in (folder, *folder.rglob("*")):
        try:
            status = path.lstat()
        except FileNotFoundError:  # a running server's short-lived file (a query's snapshot), gone meanwhile
            continue
        name = str(path.relative_to(folder)) + ("/" if stat.S_ISDIR(status.st_mode) else "")
        found[name] = oct(stat.S_IMODE(status.st_mode))
    return found


def test_a_served_data_dir_and_the_exports_are_private_to_the_servers_user(
    tmp_path: Path, permissive_umask: None
) -> None:
    data, port = tmp_path / "data", free_port()
    url = f"http://127.0.0.1:{port}"
    argv = [*SEGB, "serve", "--only", "api", "--data-dir", str(data), "--api-port", str(port)]
    with running(argv, ready=f"{url}/healthz/ready", env=clean_env(), log=tmp_path / "serve.log", timeout=180):
        posted = httpx.post(f"{url}/ttl", content=SAID, headers={"Content-Type": "text/turtle"}, timeout=60)
        assert posted.status_code == 201, posted.text
        settle(url, timeout=240)  # the views (a process of their own) have written theirs
        assert httpx.get(f"{url}/evidence", timeout=60).status_code == 200  # the signing key is made
        assert httpx.get(f"{url}/reports/conversations", timeout=60).json()["rows"]
        while_serving = modes(data)  # SQLite's write-ahead logs (-wal, -shm) exist while the server runs
    exported, bundle = tmp_path / "events.ttl", tmp_path / "bundle.zip"
    for command in (["export", "-o", str(exported)], ["evidence", "-o", str(bundle)]):
        done = subprocess.run(
            [*SEGB, *command, "--data-dir", str(data)], env=clean_env(), capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 0, done.stderr

    written = {**while_serving, **modes(data)}
    assert len(written) > 10, written  # the journal, the state, the store, the views, the log, the key
    assert any(path.endswith("-wal") for path in written), sorted(written)
    for kind in ("journal", "logs", "evidence"):
        assert any(kind in path for path in written), (kind, sorted(written))
    assert any(path.endswith((".sqlite", ".db", ".sqlite3")) for path in written), sorted(written)
    assert {path: mode for path, mode in written.items() if mode != ("0o700" if path.endswith("/") else "0o600")} == {}
    assert oct(stat.S_IMODE(exported.stat().st_mode)) == "0o600" and exported.stat().st_size > 0
    assert oct(stat.S_IMODE(bundle.stat().st_mode)) == "0o600"
