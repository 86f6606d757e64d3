"""`segb verify-evidence` against hostile bundles: a genuine bundle made by `segb evidence`, then changed as an
attacker would change it (a zip bomb, an entry a streaming reader sees but the central directory hides, a comment
or bytes after the archive, a symbolic link, malformed JSON signed with the server's own key, a bundle re-signed
with another key). Each is refused in one line, without a traceback and within bounded memory; the genuine
bundle still verifies, and without a trusted key its exit status says so."""

from __future__ import annotations

import base64
import hashlib
import io
import json
import struct
import subprocess
import sys
import zipfile
import zlib
from collections.abc import Callable, Collection
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from segb_server.backend.services.evidence.key import ServerKey, fingerprint, public_pem
from tests.cli.test_cli import SEGB, clean_env, segb
from tests.conftest import FIXTURES

pytestmark = pytest.mark.processes  # runs the segb command

Files = dict[str, bytes]
MIB = 1 << 20
SYMLINK = 0o120777 << 16
FILE = 0o600 << 16  # what zipfile writes for an entry given by name


@dataclass(frozen=True)
class Genuine:
    bundle: bytes
    key: ServerKey
    key_file: Path


@pytest.fixture(scope="module")
def genuine(tmp_path_factory: pytest.TempPathFactory) -> Genuine:
    data_dir = tmp_path_factory.mktemp("evidence")
    loaded = segb("import", "--data-dir", str(data_dir), str(FIXTURES / "sample_two_robots.ttl"))
    assert loaded.returncode == 0, loaded.stderr
    bundle = data_dir / "genuine.zip"
    made = segb("evidence", "--data-dir", str(data_dir), "--since", "2020-01-01T00:00:00Z", "-o", str(bundle))
    assert made.returncode == 0, made.stderr
    key = ServerKey.at(data_dir)  # the key `segb evidence` signed with: to sign malformed manifests as the server
    key_file = data_dir / "server.pem"
    key_file.write_bytes(key.public_pem())
    return Genuine(bundle.read_bytes(), key, key_file)


@dataclass(frozen=True)
class Checked:
    code: int
    stdout: str
    stderr: str
    peak_mb: float  # the check's maximum resident set size

    @property
    def verdict(self) -> str:
        return self.stdout.rstrip("\n").rsplit("\n", 1)[-1]


# A process's peak memory counts its parent's, when it was forked, until it runs a program of its own: the check
# is started by a small interpreter, not by this test process, and that one reports its child's peak.
PEAK_OF_CHILD = (
    "import resource, subprocess, sys; code = subprocess.call(sys.argv[2:]);"
    "open(sys.argv[1], 'w').write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)); sys.exit(code)"
)


def check(genuine: Genuine, bundle: bytes, tmp_path: Path, *, trusted: bool = True) -> Checked:
    """`segb verify-evidence` on `bundle`, with the server's key (`trusted`) or none, and its peak memory."""
    path, peak = tmp_path / "bundle.zip", tmp_path / "peak"
    path.write_bytes(bundle)
    key = ["--public-key", str(genuine.key_file)] if trusted else []
    command = [sys.executable, "-c", PEAK_OF_CHILD, str(peak), *SEGB, "verify-evidence", str(path), *key]
    run = subprocess.run(command, capture_output=True, text=True, timeout=120, env=clean_env())
    return Checked(run.returncode, run.stdout, run.stderr, int(peak.read_text()) / 1024)  # kB on Linux


def refused(checked: Checked, reason: str) -> None:
    assert "Traceback" not in checked.stdout + checked.stderr, checked.stderr
    assert checked.code == 1, (checked.stdout, checked.stderr)
    assert ": NOT verified: " in checked.verdict and reason in checked.verdict, checked.stdout


def files_of(bundle: bytes) -> Files:
    with zipfile.ZipFile(io.BytesIO(bundle)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def zipped(files: Files) -> bytes:
    """As the server writes a bundle (EvidenceService.build)."""
    archive = io.BytesIO()
    with zipfile.ZipFile(archive, "w", compression=zipfile.ZIP_DEFLATED) as bundle:
        for name, data in files.items():
            bundle.writestr(name, data)
    return archive.getvalue()


# A zip writer of our own, to make archives zipfile will not: each field is the test's to choose.


@dataclass(frozen=True)
class Entry:
    name: bytes
    stored: bytes  # the entry's data as it lies in the archive (raw deflate)
    size: int
    crc: int
    external: int = FILE
    flags: int = 0
    extra: bytes = b""


def entry(name: str, data: bytes) -> Entry:
    deflater = zlib.compressobj(6, zlib.DEFLATED, -15)
    return Entry(name.encode(), deflater.compress(data) + deflater.flush(), len(data), zlib.crc32(data))


def local_header(item: Entry) -> bytes:
    return struct.pack("<4s5H3L2H", b"PK\x03\x04", 20, item.flags, 8, 0, 0x21, item.crc, len(item.stored),
                       item.size, len(item.name), len(item.extra)) + item.name + item.extra + item.stored  # fmt: skip


def raw_zip(entries: list[Entry], *, hidden: Collection[int] = ()) -> bytes:
    """An archive of `entries` in order; those whose index is in `hidden` have a local header and data but no
    central directory record."""
    body, directory = b"", b""
    for index, item in enumerate(entries):
        if index not in hidden:
            directory += struct.pack("<4s6H3L5H2L", b"PK\x01\x02", 0x0314, 20, item.flags, 8, 0, 0x21, item.crc,
                                     len(item.stored), item.size, len(item.name), len(item.extra), 0, 0, 0,
                                     item.external, len(body)) + item.name + item.extra  # fmt: skip
        body += local_header(item)
    count = len(entries) - len(hidden)
    end = struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, count, count, len(directory), len(body), 0)
    return body + directory + end


def entries_of(genuine: Genuine) -> list[Entry]:
    return [entry(name, data) for name, data in files_of(genuine.bundle).items()]


def test_the_genuine_bundle_verifies_and_so_does_our_own_writing_of_it(genuine: Genuine, tmp_path: Path) -> None:
    """The hand-written archives below differ from the genuine one only by what each test changes."""
    for bundle in (genuine.bundle, raw_zip(entries_of(genuine))):
        checked = check(genuine, bundle, tmp_path)
        assert checked.code == 0 and checked.verdict.endswith(": verified"), checked.stdout
        assert f"signed with the server's key {genuine.key.fingerprint}" in checked.stdout


# Bombs: a small archive whose entries inflate to far more than a bundle holds.


@pytest.fixture(scope="module")
def gibibyte_of_zeros() -> Entry:
    deflater, crc, stored = zlib.compressobj(6, zlib.DEFLATED, -15), 0, []
    block = bytes(MIB)
    for _ in range(1024):
        stored.append(deflater.compress(block))
        crc = zlib.crc32(block, crc)
    return Entry(b"", b"".join(stored) + deflater.flush(), 1024 * MIB, crc)


@pytest.mark.parametrize("name", ["padding.bin", "timeline.html"])
def test_a_gibibyte_entry_in_a_one_megabyte_bundle_is_refused_before_it_is_inflated(
    genuine: Genuine, gibibyte_of_zeros: Entry, tmp_path: Path, name: str
) -> None:
    entries = [item for item in entries_of(genuine) if item.name != name.encode()]
    bundle = raw_zip([*entries, replace(gibibyte_of_zeros, name=name.encode())])
    assert len(bundle) < 2 * MIB
    checked = check(genuine, bundle, tmp_path)
    refused(checked, "more than the 512 MiB this check reads")
    assert checked.peak_mb < 150, checked.peak_mb


def test_an_entry_that_inflates_past_its_declared_size_is_cut_short(genuine: Genuine, tmp_path: Path) -> None:
    """The size the headers declare is a lie: inflating stops one byte past it, whatever the data holds."""
    entries = entries_of(genuine)
    page = next(item for item in entries if item.name == b"timeline.html")
    bomb = entry("timeline.html", bytes(256 * MIB))
    # A declared size the data's length makes plausible (no bomb by its ratio), which inflating then exceeds.
    entries[entries.index(page)] = replace(page, stored=bomb.stored, size=MIB)
    checked = check(genuine, raw_zip(entries), tmp_path)
    refused(checked, "timeline.html inflates to more than the")
    assert checked.peak_mb < 150, checked.peak_mb


def test_an_entry_under_the_cap_that_inflates_like_a_bomb_is_refused(genuine: Genuine, tmp_path: Path) -> None:
    entries = [item for item in entries_of(genuine) if item.name != b"timeline.html"]
    checked = check(genuine, raw_zip([*entries, entry("timeline.html", bytes(200 * MIB))]), tmp_path)
    refused(checked, "timeline.html would inflate")
    assert checked.peak_mb < 150, checked.peak_mb


# The archive holds the signed entries and nothing else: what a streaming reader, an unzip tool or a file
# manager shows must be what the check read.


def forged_page(genuine: Genuine) -> Entry:
    page = files_of(genuine.bundle)["timeline.html"]
    return entry("timeline.html", page.replace(b"events in time order", b"events. The robot did nothing wrong."))


def page_first(genuine: Genuine) -> bytes:
    """A forged timeline.html before the genuine archive: zipfile finds the genuine one through the central
    directory (it allows for data before the archive), a streaming reader meets the forged one first."""
    forged = local_header(forged_page(genuine))
    with zipfile.ZipFile(io.BytesIO(forged + genuine.bundle)) as archive:
        assert archive.read("timeline.html") == files_of(genuine.bundle)["timeline.html"]
    return forged + genuine.bundle


def hidden_between(genuine: Genuine) -> bytes:
    entries = entries_of(genuine)
    return raw_zip([*entries[:2], forged_page(genuine), *entries[2:]], hidden={2})


def with_attributes(external: int = FILE, flags: int = 0, extra: bytes = b"") -> Callable[[Genuine], bytes]:
    def build(genuine: Genuine) -> bytes:
        entries = entries_of(genuine)
        entries[-1] = replace(entries[-1], external=external, flags=flags, extra=extra)
        return raw_zip(entries)

    return build


def renamed_locally(genuine: Genuine) -> bytes:
    """The central directory says timeline.html; the local header (what a streaming reader goes by) another name."""
    entries = entries_of(genuine)
    assert entries[-1].name == b"timeline.html"
    name_at = sum(len(local_header(item)) for item in entries[:-1]) + 30
    bundle = bytearray(raw_zip(entries))
    bundle[name_at : name_at + 13] = b"timeline.htm\x00"
    return bytes(bundle)


UNLIKE_THE_SERVERS: dict[str, tuple[Callable[[Genuine], bytes], str]] = {
    "a local entry before the archive": (page_first, "bytes before its first entry"),
    "a local entry hidden between two": (hidden_between, "bytes it does not list, between its entries"),
    "an archive comment": (lambda g: zipped_with_comment(g.bundle), "carries a comment"),
    "bytes after the archive": (lambda g: g.bundle + b"<html>forged</html>", "bytes follow the end of the archive"),
    "a symbolic link": (with_attributes(external=SYMLINK), "timeline.html is a symbolic link"),
    "a directory attribute": (with_attributes(external=FILE | 0x10), "timeline.html has file attributes"),
    "a data descriptor": (with_attributes(flags=0x08), "timeline.html uses a data descriptor"),
    "an encrypted entry": (with_attributes(flags=0x01), "timeline.html is encrypted"),
    "an extra field naming another path": (
        with_attributes(extra=struct.pack("<HHB", 0x7075, 9, 1) + b"\0\0\0\0evil"),
        "timeline.html carries extra fields",
    ),
    "a local name unlike the central one": (renamed_locally, "its local header disagrees"),
    "a name twice": (lambda g: raw_zip([*entries_of(g), forged_page(g)]), "timeline.html is in the archive twice"),
    "a truncated archive": (lambda g: g.bundle[:-40], "not a readable evidence bundle"),
    "not an archive": (lambda g: b"%PDF-1.7\n" + bytes(100), "not a readable evidence bundle"),
}


def zipped_with_comment(bundle: bytes) -> bytes:
    archive = io.BytesIO(bundle)
    with zipfile.ZipFile(archive, "a") as writable:
        writable.comment = b"Verified by the court's expert."
    return archive.getvalue()


@pytest.mark.parametrize("change", UNLIKE_THE_SERVERS)
def test_an_archive_unlike_the_servers_is_refused_in_one_line(genuine: Genuine, tmp_path: Path, change: str) -> None:
    build, reason = UNLIKE_THE_SERVERS[change]
    checked = check(genuine, build(genuine), tmp_path)
    refused(checked, reason)
    assert checked.stdout.count("\n") == 1  # nothing of it was read: the verdict is all there is to say


# Malformed files, signed with the server's own key, so that no signature check stops the verifier before it
# reads them: each must be a verdict, not a traceback.


def signed_again(files: Files, key: ServerKey | Ed25519PrivateKey, manifest: bytes | None = None) -> bytes:
    """`files` with the manifest's hashes brought up to date (or `manifest` as given), signed with `key`."""
    if manifest is None:
        document = json.loads(files["manifest.json"])
        document["files"] = {name: hashlib.sha256(files[name]).hexdigest() for name in document["files"]}
        manifest = json.dumps(document, indent=2).encode()
    files["manifest.json"] = manifest
    files["manifest.sig"] = base64.b64encode(key.sign(manifest)) + b"\n"
    return zipped(files)


def manifest_changed(change: Callable[[dict[str, Any]], object]) -> Callable[[Genuine], bytes]:
    def build(genuine: Genuine) -> bytes:
        files = files_of(genuine.bundle)
        document = json.loads(files["manifest.json"])
        changed = change(document)
        manifest = changed if isinstance(changed, bytes) else json.dumps(document if changed is None else changed)
        return signed_again(files, genuine.key, manifest if isinstance(manifest, bytes) else manifest.encode())

    return build


def line_changed(name: str, change: Callable[[dict[str, Any]], object]) -> Callable[[Genuine], bytes]:
    """The first line of `name` changed, the manifest's hash of it updated, signed again by the server's key."""

    def build(genuine: Genuine) -> bytes:
        files = files_of(genuine.bundle)
        first, _, rest = files[name].partition(b"\n")
        line = json.loads(first)
        changed = change(line)
        files[name] = (changed if isinstance(changed, bytes) else json.dumps(line).encode()) + b"\n" + rest
        return signed_again(files, genuine.key)

    return build


def file_replaced(name: str, data: bytes) -> Callable[[Genuine], bytes]:
    def build(genuine: Genuine) -> bytes:
        files = files_of(genuine.bundle)
        files[name] = data
        return zipped(files)

    return build


def setting(path: str, value: object) -> Callable[[dict[str, Any]], None]:
    def change(document: dict[str, Any]) -> None:
        *parents, last = path.split("/")
        for part in parents:
            document = document[part]
        document[last] = value

    return change


def removing(path: str) -> Callable[[dict[str, Any]], None]:
    def change(document: dict[str, Any]) -> None:
        *parents, last = path.split("/")
        for part in parents:
            document = document[part]
        del document[last]

    return change


MALFORMED: dict[str, tuple[Callable[[Genuine], bytes], str]] = {
    "manifest not JSON": (manifest_changed(lambda m: b"{"), "manifest.json is not JSON"),
    "manifest not UTF-8": (manifest_changed(lambda m: b'{"format": "\xff"}'), "manifest.json is not JSON"),
    "manifest a list": (manifest_changed(lambda m: []), "manifest.json is not an object"),
    "manifest nested past reason": (manifest_changed(lambda m: b"[" * 100_000), "manifest.json is not JSON"),
    "manifest number of 5000 digits": (
        manifest_changed(lambda m: b'{"chain": {"head": {"sequence": 1' + b"0" * 5000 + b"}}}"),
        "manifest.json is not JSON",
    ),
    "server a string": (manifest_changed(setting("server", "segb")), "manifest.json: server is not an object"),
    "files missing": (manifest_changed(removing("files")), "manifest.json: files is missing"),
    "a file's hash a number": (
        manifest_changed(setting("files/triples.nt", 7)),
        "manifest.json: files: triples.nt is not a string",
    ),
    "head sequence a string": (
        manifest_changed(setting("chain/head/sequence", "1")),
        "manifest.json: chain: head: sequence is not an integer",
    ),
    "head sequence true": (
        manifest_changed(setting("chain/head/sequence", True)),
        "manifest.json: chain: head: sequence is not an integer",
    ),
    "redactions an object": (
        manifest_changed(setting("redactions", {"sequence": 2})),
        "manifest.json: redactions is not a list",
    ),
    "an erasure without its reason": (
        manifest_changed(setting("redactions", [{"sequence": 2}])),
        "manifest.json: redactions 1: recorded_at is missing",
    ),
    "a lone surrogate": (
        manifest_changed(lambda m: b'{"format": "\\ud800"}'),
        "manifest.json holds text that is not Unicode",
    ),
    "coverage line a number": (line_changed("coverage.jsonl", lambda c: b"7"), "coverage.jsonl line 1 is not"),
    "coverage sequence a string": (
        line_changed("coverage.jsonl", setting("sequence", "1")),
        "coverage.jsonl line 1: sequence is not an integer",
    ),
    "coverage withheld not hex": (
        line_changed("coverage.jsonl", setting("withheld", ["zz" * 32])),
        "coverage.jsonl line 1: withheld 1 is not a SHA-256 digest in hex",
    ),
    "coverage digest cut short": (
        line_changed("coverage.jsonl", setting("redacted", ["ab" * 31])),
        "coverage.jsonl line 1: redacted 1 is not a SHA-256 digest in hex",
    ),
    "coverage disclosed a string": (
        line_changed("coverage.jsonl", setting("disclosed", "<a> <b> <c> .")),
        "coverage.jsonl line 1: disclosed is not a list",
    ),
    "coverage disclosed a number": (
        line_changed("coverage.jsonl", setting("disclosed", [7])),
        "coverage.jsonl line 1: disclosed 1 is not a string",
    ),
    "coverage not JSON": (line_changed("coverage.jsonl", lambda c: b"{]"), "coverage.jsonl line 1 is not JSON"),
    "receipt sequence a string": (
        line_changed("receipts.jsonl", setting("receipt/sequence", "1")),
        "receipts.jsonl line 1: receipt: sequence is not an integer",
    ),
    "receipt a list": (
        line_changed("receipts.jsonl", setting("receipt", [])),
        "receipts.jsonl line 1: receipt is not an object",
    ),
    "erasure record of the wrong shape": (
        line_changed("receipts.jsonl", setting("redaction", {"receipts": "all"})),
        "receipts.jsonl line 1: redaction: receipts is not a list",
    ),
    "signature not base64": (file_replaced("manifest.sig", "signé\n".encode()), "the signature does not match"),
    "public key not PEM": (file_replaced("public-key.pem", b"-----BEGIN PUBLIC KEY-----\n"), "unreadable public key"),
}


@pytest.mark.parametrize("malformed", MALFORMED)
def test_a_malformed_file_is_a_verdict_not_a_traceback(genuine: Genuine, tmp_path: Path, malformed: str) -> None:
    build, reason = MALFORMED[malformed]
    refused(check(genuine, build(genuine), tmp_path), reason)


def test_text_from_the_bundle_cannot_drive_the_terminal(genuine: Genuine, tmp_path: Path) -> None:
    """An erasure's reason is printed: an escape sequence in it is shown, not obeyed (it could clear the line
    and print a verdict of its own)."""

    def erasure(manifest: dict[str, Any]) -> None:
        manifest["redactions"] = [{"sequence": 1, "recorded_at": "2026-03-10T09:00:00Z", "user": "dpo",
                                   "kind": "human", "reason": "\x1b[2K\rverified", "triples_removed": 0,
                                   "receipts_in_window": []}]  # fmt: skip

    checked = check(genuine, manifest_changed(erasure)(genuine), tmp_path)
    assert "\x1b" not in checked.stdout and "\\x1b[2K\\rverified" in checked.stdout, checked.stdout


# Who signed: without the server's key, a bundle is intact under the key it carries, and no more.


def resigned_by_another_key(genuine: Genuine) -> bytes:
    """A changed literal, then the bundle made consistent again and signed with the attacker's own key."""
    files = files_of(genuine.bundle)
    files["triples.nt"] = files["triples.nt"].replace(b'"Bob"@en', b'"Robert"@en')
    other = Ed25519PrivateKey.generate()
    files["public-key.pem"] = public_pem(other.public_key())
    manifest = json.loads(files["manifest.json"])
    manifest["server"]["key_fingerprint"] = fingerprint(other.public_key())
    files["manifest.json"] = json.dumps(manifest).encode()
    return signed_again(files, other)


def test_a_bundle_re_signed_by_another_key_is_never_verified(genuine: Genuine, tmp_path: Path) -> None:
    bundle = resigned_by_another_key(genuine)
    against_the_servers = check(genuine, bundle, tmp_path)
    refused(against_the_servers, "signed with another key")
    assert "signed with the server's key" not in against_the_servers.stdout  # the signature is not the server's
    untrusted = check(genuine, bundle, tmp_path, trusted=False)
    assert untrusted.code == 3 and "Traceback" not in untrusted.stderr, untrusted.stdout
    carried = json.loads(files_of(bundle)["manifest.json"])["server"]["key_fingerprint"]
    assert "untrusted key" in untrusted.verdict and carried in untrusted.verdict, untrusted.verdict
    assert not untrusted.verdict.endswith("verified"), untrusted.verdict


def test_the_genuine_bundle_without_the_servers_key_is_intact_but_not_verified(
    genuine: Genuine, tmp_path: Path
) -> None:
    checked = check(genuine, genuine.bundle, tmp_path, trusted=False)
    assert checked.code == 3, checked.stdout
    assert genuine.key.fingerprint in checked.verdict and "--public-key" in checked.verdict, checked.verdict
    assert not checked.verdict.endswith("verified"), checked.verdict
