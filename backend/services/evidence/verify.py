"""Checking an evidence bundle offline, with nothing but the bundle and the server's public key: the signature,
every file against the signed manifest, the chain of receipts up to the signed head, every disclosed triple
against its receipt's digest, and every triple of the window covered by a receipt. Each failure says what
failed and where; erasures in the bundle's range are told (what was removed, when, by whom, why)."""

from __future__ import annotations

import base64
import hashlib
import json
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature

from segb_server.backend.services.evidence import layout
from segb_server.backend.services.evidence.key import fingerprint, read_public_key
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.redaction import DIGEST_BYTES, canonical_json, content_digest

_RECEIPT_FIELDS = {f.name for f in fields(Receipt)}


@dataclass
class Report:
    problems: list[str] = field(default_factory=list)
    facts: list[str] = field(default_factory=list)

    @property
    def valid(self) -> bool:
        return not self.problems


def verify_bundle(path: Path, public_key_pem: bytes | None = None) -> Report:
    report = Report()
    try:
        with zipfile.ZipFile(path) as bundle:
            names = bundle.namelist()
            files = {name: bundle.read(name) for name in names}
    except (OSError, zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError) as error:
        # A damaged archive fails in several ways: a bad checksum, a deflate stream that does not decode, a
        # compression method or an encryption this reader does not know. Each is a bundle not verified.
        report.problems.append(f"not a readable evidence bundle: {error}")
        return report
    # Archive tools differ on which of two entries of one name they show: whichever one this check read, an
    # investigator may open the other.
    for name in sorted({name for name in names if names.count(name) > 1}):
        report.problems.append(f"{name} is in the archive twice: a reader may be shown either copy")
    missing = [name for name in (layout.MANIFEST, layout.SIGNATURE, *layout.SIGNED_FILES) if name not in files]
    if missing:
        report.problems.append(f"files missing from the bundle: {', '.join(missing)}")
        return report
    manifest = _signed_manifest(files, public_key_pem, report)
    if manifest is None:
        return report
    _check_files(files, manifest, report)
    receipts = _check_chain(files[layout.RECEIPTS], manifest, report)
    disclosed = _check_coverage(files[layout.COVERAGE], receipts, report)
    _check_triples(files[layout.TRIPLES], disclosed, report)
    _tell_redactions(manifest, report)
    return report


def _signed_manifest(files: dict[str, bytes], expected_pem: bytes | None, report: Report) -> dict[str, Any] | None:
    try:
        bundled = read_public_key(files[layout.PUBLIC_KEY])
        expected = read_public_key(expected_pem) if expected_pem is not None else None
    except ValueError as error:
        report.problems.append(f"unreadable public key: {error}")
        return None
    key = expected or bundled
    if expected is not None and fingerprint(expected) != fingerprint(bundled):
        report.problems.append(
            f"signed with another key: the bundle carries key {fingerprint(bundled)}, the server's key is "
            f"{fingerprint(expected)}"
        )
    try:
        key.verify(base64.b64decode(files[layout.SIGNATURE].strip(), validate=True), files[layout.MANIFEST])
    except (InvalidSignature, ValueError):
        report.problems.append(
            f"the signature does not match {layout.MANIFEST} for key {fingerprint(key)}: the manifest was changed "
            "after signing, or the signature is not the server's"
        )
    if expected is None:
        report.facts.append(
            f"signed with the key the bundle carries, {fingerprint(bundled)}: compare it with the server's published "
            "key (GET /.well-known/segb-evidence-key), or pass --public-key"
        )
    else:
        report.facts.append(f"signed with the server's key {fingerprint(expected)}")
    try:
        manifest: dict[str, Any] = json.loads(files[layout.MANIFEST])
    except ValueError as error:
        report.problems.append(f"{layout.MANIFEST} is not JSON: {error}")
        return None
    if manifest.get("server", {}).get("key_fingerprint") != fingerprint(key):
        report.problems.append("the manifest names another signing key than the one that verifies it")
    return manifest


def _check_files(files: dict[str, bytes], manifest: dict[str, Any], report: Report) -> None:
    """Every file the bundle must hold matches the signed manifest, and the archive holds nothing else: a file
    beside the signed ones would be read as part of the evidence without being vouched for."""
    listed = manifest.get("files", {})
    for name in layout.SIGNED_FILES:
        if hashlib.sha256(files[name]).hexdigest() != listed.get(name):
            report.problems.append(f"{name} was changed after signing (its SHA-256 is not the manifest's)")
    for name in sorted(set(files) - {layout.MANIFEST, layout.SIGNATURE, *layout.SIGNED_FILES}):
        report.problems.append(f"{name} is not one of the files the signed manifest lists")


def _entries(data: bytes, what: str, report: Report) -> Iterator[dict[str, Any]]:
    for number, line in enumerate(data.splitlines(), 1):
        try:
            yield json.loads(line)
        except ValueError:
            report.problems.append(f"{what} line {number} is not JSON")


def _check_chain(data: bytes, manifest: dict[str, Any], report: Report) -> dict[int, tuple[Receipt, Any]]:
    """The receipts by sequence (with an erasure's record), after checking each hash and link."""
    chain: dict[int, tuple[Receipt, Any]] = {}
    previous: Receipt | None = None
    for entry in _entries(data, layout.RECEIPTS, report):
        public = entry.get("receipt", {})
        receipt = Receipt(**{name: public.get(name) for name in _RECEIPT_FIELDS})
        chain[receipt.sequence] = (receipt, entry.get("redaction"))
        where = f"receipt {receipt.sequence} ({receipt.log_id})"
        if receipt.computed_hash() != receipt.receipt_hash:
            report.problems.append(f"{where} was altered: it no longer hashes to its receipt_hash")
        if previous is not None and receipt.sequence != previous.sequence + 1:
            report.problems.append(
                f"receipts {previous.sequence + 1}…{receipt.sequence - 1} are missing: the chain jumps from "
                f"{previous.sequence} to {receipt.sequence}"
            )
        elif previous is not None and receipt.previous_hash != previous.receipt_hash:
            report.problems.append(f"{where} does not follow receipt {previous.sequence}: its previous_hash differs")
        record = entry.get("redaction")
        if record is not None and hashlib.sha256(canonical_json(record)).hexdigest() != receipt.content_sha256:
            report.problems.append(f"the record of erasure {receipt.sequence} was changed")
        previous = receipt
    head = manifest.get("chain", {}).get("head")
    if head is not None and (previous is None or previous.sequence != head["sequence"]):
        report.problems.append(f"the chain ends at {previous.sequence if previous else 'nothing'}, not at the "
                               f"signed head {head['sequence']}")  # fmt: skip
    elif head is not None and previous is not None and previous.receipt_hash != head["receipt_hash"]:
        report.problems.append(f"the chain's last receipt is not the signed head {head['sequence']}")
    elif previous is not None:
        report.facts.append(f"the chain of {len(chain)} receipts is whole up to the signed head {previous.sequence}")
    return chain


def _check_coverage(data: bytes, chain: dict[int, tuple[Receipt, Any]], report: Report) -> dict[bytes, int]:
    """Every disclosed line (→ its receipt), after checking each receipt's share against its digest."""
    disclosed: dict[bytes, int] = {}
    for entry in _entries(data, layout.COVERAGE, report):
        sequence = entry.get("sequence")
        if sequence not in chain:
            report.problems.append(f"coverage names receipt {sequence}, which the bundle's chain does not hold")
            continue
        receipt = chain[sequence][0]
        lines = [line.encode("utf-8") for line in entry.get("disclosed", [])]
        document = b"".join(line + b"\n" for line in lines)
        withheld = bytes.fromhex("".join(entry.get("withheld", [])))
        redacted = bytes.fromhex("".join(entry.get("redacted", [])))
        erased = _erased_from(sequence, chain)
        if len(redacted) != erased * DIGEST_BYTES:
            report.problems.append(
                f"receipt {sequence} lacks {len(redacted) // DIGEST_BYTES} lines; the erasures in the chain account "
                f"for {erased}"
            )
        if receipt.content_digest is not None:
            matches = content_digest(document, withheld + redacted) == receipt.content_digest
        else:  # a receipt from before content digests: its whole content is disclosed
            expected = _remaining_sha256(sequence, chain) or receipt.content_sha256
            matches = hashlib.sha256(document).hexdigest() == expected
        if not matches:
            report.problems.append(
                f"receipt {sequence} ({receipt.log_id}) does not cover what the bundle discloses for it: a triple "
                "was changed, added or dropped"
            )
        for line in lines:
            disclosed[line] = sequence
    return disclosed


def _erased_from(sequence: int, chain: dict[int, tuple[Receipt, Any]]) -> int:
    return sum(
        item["triples_removed"]
        for _receipt, record in chain.values()
        if record is not None
        for item in record.get("receipts", [])
        if item.get("sequence") == sequence
    )


def _remaining_sha256(sequence: int, chain: dict[int, tuple[Receipt, Any]]) -> str | None:
    found = None
    for number in sorted(chain):
        record = chain[number][1]
        for item in (record or {}).get("receipts", []):
            if item.get("sequence") == sequence:
                found = item.get("remaining_sha256")
    return found


def _check_triples(data: bytes, disclosed: dict[bytes, int], report: Report) -> None:
    lines = data.splitlines()
    present = set(lines)
    for line in lines:
        if line not in disclosed:
            report.problems.append(f"a triple of {layout.TRIPLES} is covered by no receipt: {_short(line)}")
    for line, sequence in disclosed.items():
        if line not in present:
            report.problems.append(f"a triple receipt {sequence} discloses is missing from {layout.TRIPLES}: "
                                   f"{_short(line)}")  # fmt: skip
    if not report.problems and not present:
        report.facts.append(
            "the window holds no triple: nothing logged falls in it (check the robot's IRI and the times "
            "in the manifest's query)"
        )
    elif not report.problems:
        report.facts.append(f"{len(present)} triples, each covered by a receipt")


def _tell_redactions(manifest: dict[str, Any], report: Report) -> None:
    for erasure in manifest.get("redactions", []):
        report.facts.append(
            f"erasure {erasure['sequence']} on {erasure['recorded_at']} by {erasure['user']} ({erasure['kind']}: "
            f"{erasure['reason']}) removed {erasure['triples_removed']} triples, from "
            f"{len(erasure['receipts_in_window'])} of this bundle's receipts"
        )


def _short(line: bytes) -> str:
    text = line.decode("utf-8", "replace")
    return text if len(text) <= 160 else text[:157] + "…"
