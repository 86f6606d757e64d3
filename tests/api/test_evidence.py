"""Evidence bundles through the API and `segb verify-evidence`, with what the PyPI client publishes: a bundle
verifies offline with the server's published key; each kind of tampering is caught and named; after an erasure
a bundle still verifies and says what was removed, when, by whom and why."""

from __future__ import annotations

import base64
import hashlib
import io
import json
import warnings
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from segb_server.backend.api.app import create_app
from segb_server.backend.services.evidence.key import fingerprint, public_pem
from tests.cli.test_cli import segb
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.people import INES_SAYS, ROBOT_REPLIES, Visit, care_home

pytestmark = pytest.mark.processes  # checks bundles with the segb command

WINDOW = {"since": "2026-03-10T09:00:00Z", "until": "2026-03-10T09:00:25Z"}
Files = dict[str, bytes]


@dataclass
class Served:
    url: str
    visit: Visit
    key: bytes  # the server's public key, as published
    data_dir: Path


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    data_dir = tmp_path_factory.mktemp("evidence")
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=data_dir))) as server:
        visit = care_home()
        visit.publish_steps(server.url)
        key = httpx.get(f"{server.url}/.well-known/segb-evidence-key")
        assert key.status_code == 200 and key.headers["x-key-fingerprint"]
        yield Served(server.url, visit, key.content, data_dir)


def bundle_of(served: Served, **params: str) -> Files:
    answer = httpx.get(f"{served.url}/evidence", params=params, timeout=60)
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"] == "application/zip"
    with zipfile.ZipFile(io.BytesIO(answer.content)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def written(files: Files, path: Path) -> Path:
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return path


def verify(served: Served, files: Files, tmp_path: Path, key: bytes | None = None) -> tuple[int, str]:
    (tmp_path / "server.pem").write_bytes(key or served.key)
    checked = segb("verify-evidence", str(written(files, tmp_path / "bundle.zip")), "--public-key",
                   str(tmp_path / "server.pem"))  # fmt: skip
    return checked.returncode, checked.stdout


def test_a_bundle_holds_the_window_as_sent_and_verifies_offline(served: Served, tmp_path: Path) -> None:
    files = bundle_of(served, robot=str(served.visit.iris["ari"]), **WINDOW)
    manifest = json.loads(files["manifest.json"])
    assert manifest["query"] == {"robot": str(served.visit.iris["ari"]), **WINDOW}
    assert manifest["exported_by"] == "anonymous_user" and manifest["chain"]["head"]["sequence"] > 1
    triples = files["triples.nt"].decode()
    # ARI's words and what it heard in the window, exactly as the client sent them; TIAGo's are not in it.
    assert INES_SAYS[0] in triples and ROBOT_REPLIES[0] in triples and ROBOT_REPLIES[1] not in triples
    assert '"0.8"^^<http://www.w3.org/2001/XMLSchema#float>' in triples  # the emotion's intensity as sent
    timeline = files["timeline.html"].decode()
    assert "<script" not in timeline and ROBOT_REPLIES[0] in timeline
    code, out = verify(served, files, tmp_path)
    assert code == 0, out
    assert "verified" in out and f"signed with the server's key {fingerprint_of(served.key)}" in out


def fingerprint_of(pem: bytes) -> str:
    from segb_server.backend.services.evidence.key import read_public_key

    return fingerprint(read_public_key(pem))


def changed_literal(files: Files) -> None:
    files["triples.nt"] = files["triples.nt"].replace(ROBOT_REPLIES[0].encode(), b"That sounds awful.")


def dropped_triple(files: Files) -> None:
    lines = files["triples.nt"].splitlines(keepends=True)
    files["triples.nt"] = b"".join(line for line in lines if ROBOT_REPLIES[0].encode() not in line)


def removed_receipt(files: Files) -> None:
    lines = files["receipts.jsonl"].splitlines(keepends=True)
    files["receipts.jsonl"] = b"".join(lines[:1] + lines[2:])


def forged_signature(files: Files) -> None:
    files["manifest.sig"] = base64.b64encode(bytes(64)) + b"\n"


def resigned_by_another_key(files: Files, *, change: bool = True) -> None:
    """Change a literal, then make the bundle consistent again and sign it with a key of one's own."""
    if change:
        changed_literal(files)
    other = Ed25519PrivateKey.generate()
    files["public-key.pem"] = public_pem(other.public_key())
    manifest = json.loads(files["manifest.json"])
    manifest["server"]["key_fingerprint"] = fingerprint(other.public_key())
    manifest["files"] = {name: hashlib.sha256(files[name]).hexdigest() for name in manifest["files"]}
    files["manifest.json"] = json.dumps(manifest).encode()
    files["manifest.sig"] = base64.b64encode(other.sign(files["manifest.json"]))


def added_file(files: Files) -> None:
    files["report.txt"] = b"A report that seems to come with the evidence.\n"


TAMPERING: dict[str, tuple[Callable[[Files], None], list[str]]] = {
    "changed literal": (changed_literal, ["triples.nt was changed after signing", "covered by no receipt"]),
    "dropped triple": (dropped_triple, ["triples.nt was changed after signing", "is missing from triples.nt"]),
    "removed receipt": (removed_receipt, ["receipts.jsonl was changed after signing", "are missing: the chain jumps"]),
    "forged signature": (forged_signature, ["the signature does not match manifest.json"]),
    "re-signed by another key": (resigned_by_another_key, ["signed with another key"]),
    "added file": (added_file, ["report.txt is not one of the files the signed manifest lists"]),
}


@pytest.mark.parametrize("tampering", TAMPERING)
def test_each_kind_of_tampering_is_caught_and_named(served: Served, tmp_path: Path, tampering: str) -> None:
    files = bundle_of(served, **WINDOW)
    change, messages = TAMPERING[tampering]
    change(files)
    code, out = verify(served, files, tmp_path)
    assert code == 1 and "NOT verified" in out
    for message in messages:
        assert message in out, out


def test_a_file_named_twice_is_caught(served: Served, tmp_path: Path) -> None:
    """Archive tools differ on which of two entries of one name they extract: a forged copy beside the genuine
    one must not pass because the verifier happened to read the genuine one."""
    files = bundle_of(served, **WINDOW)
    bundle = tmp_path / "doubled.zip"
    with warnings.catch_warnings(), zipfile.ZipFile(bundle, "w") as archive:
        warnings.simplefilter("ignore", UserWarning)  # zipfile warns of the duplicate name it is asked to write
        archive.writestr("triples.nt", files["triples.nt"].replace(ROBOT_REPLIES[0].encode(), b"FORGED"))
        for name, data in files.items():
            archive.writestr(name, data)
    (tmp_path / "server.pem").write_bytes(served.key)
    checked = segb("verify-evidence", str(bundle), "--public-key", str(tmp_path / "server.pem"))
    assert checked.returncode == 1 and "NOT verified" in checked.stdout
    assert "triples.nt is in the archive twice" in checked.stdout, checked.stdout


def test_a_bundle_corrupted_inside_its_compressed_data_is_refused_without_a_traceback(
    served: Served, tmp_path: Path
) -> None:
    # A byte flipped inside a file's deflated data makes it unreadable (or fail the archive's checksum): the
    # verifier says the bundle is not verified, as it says of any other damage, and prints no Python traceback.
    files = bundle_of(served, **WINDOW)
    (tmp_path / "server.pem").write_bytes(served.key)
    bundle = tmp_path / "deflated.zip"
    with zipfile.ZipFile(bundle, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    genuine = bundle.read_bytes()
    with zipfile.ZipFile(bundle) as archive:
        entries = [(info.header_offset + 30 + len(info.filename) + len(info.extra), info.compress_size)
                   for info in archive.infolist() if info.compress_size > 8]  # fmt: skip
    for start, size in entries:
        for at in (start, start + size // 2):
            damaged = bytearray(genuine)
            damaged[at] ^= 0x5A
            (tmp_path / "damaged.zip").write_bytes(bytes(damaged))
            key = str(tmp_path / "server.pem")
            checked = segb("verify-evidence", str(tmp_path / "damaged.zip"), "--public-key", key)
            assert checked.returncode == 1 and "NOT verified" in checked.stdout, (at, checked.stdout, checked.stderr)
            assert "Traceback" not in checked.stderr, checked.stderr


def test_a_re_signed_bundle_passes_only_against_its_own_key(served: Served, tmp_path: Path) -> None:
    files = bundle_of(served, **WINDOW)
    resigned_by_another_key(files, change=False)
    assert verify(served, files, tmp_path)[0] == 1
    bundle = written(files, tmp_path / "resigned.zip")
    unanchored = segb("verify-evidence", str(bundle))
    # Without the server's key the signature checks against the bundle's own key: intact, and no more than that
    # (exit 3, not 0: a script cannot take it for verified).
    assert unanchored.returncode == 3 and "compare it with the server's published key" in unanchored.stdout
    assert "signed by an untrusted key" in unanchored.stdout


def test_after_an_erasure_a_bundle_verifies_and_says_what_was_removed(served: Served, tmp_path: Path) -> None:
    before = bundle_of(served, robot=str(served.visit.iris["ari"]))
    erased = httpx.post(
        f"{served.url}/humans/erase",
        json={"iri": str(served.visit.iris["ines"]), "reason": "Request by the data subject"},
        timeout=120,
    ).json()
    after = bundle_of(served, robot=str(served.visit.iris["ari"]))
    assert INES_SAYS[0] in before["triples.nt"].decode() and INES_SAYS[0] not in after["triples.nt"].decode()
    code, out = verify(served, after, tmp_path)
    assert code == 0, out
    redactions = json.loads(after["manifest.json"])["redactions"]
    assert [(r["log_id"], r["user"], r["reason"], r["triples_removed"]) for r in redactions] == [
        (erased["log_id"], "anonymous_user", "Request by the data subject", erased["triples_removed"])
    ]
    assert "by anonymous_user (human: Request by the data subject) removed" in out
    # The bundle made before the erasure still verifies on its own: it is signed evidence of that moment.
    code, out = verify(served, before, tmp_path)
    assert code == 0, out


def test_an_empty_window_verifies_and_says_it_holds_nothing(served: Served, tmp_path: Path) -> None:
    """A robot's IRI mistyped, or hours beside its events: a bundle of nothing is true evidence of nothing, and
    the check says so rather than look like a bundle of something."""
    files = bundle_of(served, robot="https://example.org/robots/ari/robot_ari", **WINDOW)
    code, out = verify(served, files, tmp_path)
    assert code == 0, out
    assert "the window holds no triple" in out and "check the robot's IRI and the times" in out
    code, out = verify(served, bundle_of(served, **WINDOW), tmp_path)
    assert code == 0 and "the window holds no triple" not in out


def test_a_bad_window_is_refused_by_name(served: Served) -> None:
    answer = httpx.get(f"{served.url}/evidence", params={"since": "yesterday"})
    assert (answer.status_code, answer.json()["error"]) == (422, "invalid_parameter")
    assert "since" in answer.json()["detail"]


def test_the_signing_key_is_the_servers_own_and_private(served: Served) -> None:
    key_file = served.data_dir / "evidence-key.pem"
    assert key_file.stat().st_mode & 0o777 == 0o600
    printed = segb("evidence-key", "--data-dir", str(served.data_dir))
    assert printed.returncode == 0 and printed.stdout.encode() == served.key
