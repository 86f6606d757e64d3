"""Checking an evidence bundle offline, with nothing but the bundle and the server's public key: the signature,
every file against the signed manifest, the chain of receipts up to the signed head, every disclosed triple
against its receipt's digest, and every triple of the window covered by a receipt. Each failure says what
failed and where; erasures in the bundle's range are told (what was removed, when, by whom, why).

Nothing in the bundle is trusted before it is checked: the archive is read strictly and within a size limit
(archive.py), its JSON field by field (shapes.py), so a hostile bundle is a verdict, never a traceback. Which key
signed is part of the verdict: `Report.trusted` only when it is the key the caller gave."""

from __future__ import annotations

import base64
import hashlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from cryptography.exceptions import InvalidSignature, UnsupportedAlgorithm
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from segb_server.backend.services.evidence import layout
from segb_server.backend.services.evidence.archive import ArchiveRefused, entries_of, read_entry
from segb_server.backend.services.evidence.key import fingerprint, read_public_key
from segb_server.backend.services.evidence.shapes import (
    Link,
    Malformed,
    Manifest,
    Share,
    chain_of,
    coverage_of,
    manifest_of,
)
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.redaction import DIGEST_BYTES, canonical_json, content_digest

DEFAULT_LIMIT = 512 << 20  # bytes the bundle's files may inflate to in all (--max-size): the checks hold them
EXPECTED = (layout.MANIFEST, layout.SIGNATURE, *layout.SIGNED_FILES)


@dataclass
class Report:
    problems: list[str] = field(default_factory=list)
    facts: list[str] = field(default_factory=list)
    signer: str | None = None  # the fingerprint of the key the signature was checked with
    trusted: bool = False  # that key was given as the server's, not taken from the bundle

    @property
    def valid(self) -> bool:
        return not self.problems


def verify_bundle(path: Path, public_key_pem: bytes | None = None, limit: int = DEFAULT_LIMIT) -> Report:
    """Every check of the bundle at `path`; `limit`: the bytes its files may inflate to in all."""
    report = Report()
    files = _files(path, limit, report)
    if files is None:
        return report
    try:
        manifest = _signed_manifest(files, public_key_pem, report)
        if manifest is None:
            return report
        _check_files(files, manifest, report)
        chain = _check_chain(chain_of(files[layout.RECEIPTS]), manifest, report)
        disclosed = _check_coverage(coverage_of(files[layout.COVERAGE]), chain, report)
        _check_triples(files[layout.TRIPLES], disclosed, report)
        _tell_redactions(manifest, report)
    except Malformed as error:
        report.problems.append(str(error))
    return report


def _files(path: Path, limit: int, report: Report) -> dict[str, bytes] | None:
    """The bundle's files, once the archive is known to be exactly the server's kind holding exactly them."""
    try:
        with path.open("rb") as file:
            entries = entries_of(file, limit)
            report.problems += _name_problems([entry.name for entry in entries])
            if report.problems:  # nothing it should not hold is inflated
                return None
            return {entry.name: read_entry(file, entry) for entry in entries}
    except OSError as error:
        report.problems.append(f"not a readable evidence bundle: {error}")
    except ArchiveRefused as error:
        report.problems.append(str(error))
    return None


def _name_problems(names: list[str]) -> list[str]:
    # Archive tools differ on which of two entries of one name they show: whichever one this check read, an
    # investigator may open the other. A file beside the signed ones would be read as part of the evidence
    # without being vouched for.
    problems = [f"{name} is in the archive twice: a reader may be shown either copy"
                for name in sorted({name for name in names if names.count(name) > 1})]  # fmt: skip
    problems += [f"{name} is not one of the files the signed manifest lists"
                 for name in dict.fromkeys(names) if name not in EXPECTED]  # fmt: skip
    missing = [name for name in EXPECTED if name not in names]
    if missing:
        problems.append(f"files missing from the bundle: {', '.join(missing)}")
    return problems


def _signed_manifest(files: dict[str, bytes], expected_pem: bytes | None, report: Report) -> Manifest | None:
    try:
        bundled = read_public_key(files[layout.PUBLIC_KEY])
    except (ValueError, UnsupportedAlgorithm) as error:
        report.problems.append(f"unreadable public key in {layout.PUBLIC_KEY}: {error}")
        return None
    try:
        expected = read_public_key(expected_pem) if expected_pem is not None else None
    except (ValueError, UnsupportedAlgorithm) as error:
        report.problems.append(f"unreadable public key given with --public-key: {error}")
        return None
    key = expected or bundled
    report.signer, report.trusted = fingerprint(key), expected is not None
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
    else:
        _tell_signer(report, bundled, expected)
    manifest = manifest_of(files[layout.MANIFEST])
    if manifest.key_fingerprint != fingerprint(key):
        report.problems.append("the manifest names another signing key than the one that verifies it")
    return manifest


def _tell_signer(report: Report, bundled: Ed25519PublicKey, expected: Ed25519PublicKey | None) -> None:
    if expected is None:
        report.facts.append(
            f"signed with the key the bundle carries, {fingerprint(bundled)}: compare it with the server's published "
            "key (GET /.well-known/segb-evidence-key), or pass --public-key"
        )
    elif fingerprint(expected) == fingerprint(bundled):
        report.facts.append(f"signed with the server's key {fingerprint(expected)}")


def _check_files(files: dict[str, bytes], manifest: Manifest, report: Report) -> None:
    """Every file the bundle must hold matches the signed manifest (the archive holds nothing else: _files)."""
    for name in layout.SIGNED_FILES:
        if hashlib.sha256(files[name]).hexdigest() != manifest.files.get(name):
            report.problems.append(f"{name} was changed after signing (its SHA-256 is not the manifest's)")


def _check_chain(links: list[Link], manifest: Manifest, report: Report) -> dict[int, Link]:
    """The receipts by sequence (with an erasure's record), after checking each hash and link."""
    chain: dict[int, Link] = {}
    previous: Receipt | None = None
    for link in links:
        receipt = link.receipt
        chain[receipt.sequence] = link
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
        record = link.record
        if record is not None and hashlib.sha256(canonical_json(record)).hexdigest() != receipt.content_sha256:
            report.problems.append(f"the record of erasure {receipt.sequence} was changed")
        previous = receipt
    if manifest.head is not None and (previous is None or previous.sequence != manifest.head[0]):
        report.problems.append(f"the chain ends at {previous.sequence if previous else 'nothing'}, not at the "
                               f"signed head {manifest.head[0]}")  # fmt: skip
    elif manifest.head is not None and previous is not None and previous.receipt_hash != manifest.head[1]:
        report.problems.append(f"the chain's last receipt is not the signed head {manifest.head[0]}")
    elif previous is not None:
        report.facts.append(f"the chain of {len(chain)} receipts is whole up to the signed head {previous.sequence}")
    return chain


def _check_coverage(shares: list[Share], chain: dict[int, Link], report: Report) -> dict[bytes, int]:
    """Every disclosed line (→ its receipt), after checking each receipt's share against its digest."""
    disclosed: dict[bytes, int] = {}
    erased, remaining = _erasures(chain)
    for share in shares:
        sequence = share.sequence
        if sequence not in chain:
            report.problems.append(f"coverage names receipt {sequence}, which the bundle's chain does not hold")
            continue
        receipt = chain[sequence].receipt
        document = b"".join(line + b"\n" for line in share.disclosed)
        if len(share.redacted) != erased[sequence] * DIGEST_BYTES:
            report.problems.append(
                f"receipt {sequence} lacks {len(share.redacted) // DIGEST_BYTES} lines; the erasures in the chain "
                f"account for {erased[sequence]}"
            )
        if receipt.content_digest is not None:
            matches = content_digest(document, share.withheld + share.redacted) == receipt.content_digest
        else:  # a receipt from before content digests: its whole content is disclosed
            expected = remaining.get(sequence) or receipt.content_sha256
            matches = hashlib.sha256(document).hexdigest() == expected
        if not matches:
            report.problems.append(
                f"receipt {sequence} ({receipt.log_id}) does not cover what the bundle discloses for it: a triple "
                "was changed, added or dropped"
            )
        for line in share.disclosed:
            disclosed[line] = sequence
    return disclosed


def _erasures(chain: dict[int, Link]) -> tuple[Counter[int], dict[int, str | None]]:
    """For each post an erasure redacted: the lines removed from it in all, and the SHA-256 of what the latest
    erasure left (read once: a post per coverage line times every erasure would let a bundle stall the check)."""
    erased: Counter[int] = Counter()
    remaining: dict[int, str | None] = {}
    for number in sorted(chain):
        for item in chain[number].redacted:
            erased[item.sequence] += item.triples_removed
            remaining[item.sequence] = item.remaining_sha256
    return erased, remaining


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


def _tell_redactions(manifest: Manifest, report: Report) -> None:
    for erasure in manifest.redactions:
        report.facts.append(
            f"erasure {erasure.sequence} on {erasure.recorded_at} by {erasure.user} ({erasure.kind}: "
            f"{erasure.reason}) removed {erasure.triples_removed} triples, from "
            f"{len(erasure.receipts_in_window)} of this bundle's receipts"
        )


def _short(line: bytes) -> str:
    text = line.decode("utf-8", "replace")
    return text if len(text) <= 160 else text[:157] + "…"
