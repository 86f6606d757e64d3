"""Receipts: what the journal records of each accepted post or clearing, and the hash chain that binds them.

Each receipt's hash covers its fields and the previous receipt's hash, so editing or deleting a stored receipt
breaks the chain at that point and `verify` names it. A receipt also covers `content_sha256`, the SHA-256 of
the post's new triples as the journal keeps them, so a deep verification catches edited content too.
Truncating the newest receipts, or rewriting every receipt from some point on, cannot be detected from the
file alone: an auditor who wants that keeps a copy of the newest `receipt_hash` elsewhere.

A post's receipt also covers `content_digest`, a digest of its triples that survives an erasure: the SHA-256 of
the sorted SHA-256 digests of its lines. An erasure removes lines from a post's content and keeps their line
digests, so the remaining lines still prove they were part of what the receipt covered (redaction.py).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, fields
from typing import Literal

GENESIS_HASH = "0" * 64
Action = Literal["ingest", "delete_all", "erase"]
BrokenReason = Literal[
    "hash mismatch",
    "previous hash does not match",
    "sequence gap",
    "content does not match",
    "redaction does not match",
]
# Fields a receipt covers only where it has them: older receipts, written before they existed, keep verifying.
OPTIONAL_FIELDS = ("content_sha256", "content_digest", "triples_withheld")


@dataclass(frozen=True)
class Receipt:
    """What one accepted post, clearing or erasure did, and where it sits in the chain. `content_sha256` is None
    only on receipts written before the journal kept posts' content; `content_digest` and `triples_withheld` on
    receipts written before erasures existed (and on clearings and erasures, which carry no triples)."""

    sequence: int
    log_id: str
    action: str
    user: str
    claimed_user: str | None
    recorded_at: str
    payload_sha256: str
    triples_received: int
    triples_new: int
    triples_removed: int
    content_sha256: str | None
    previous_hash: str
    receipt_hash: str
    content_digest: str | None = None  # sha256 of the sorted sha256 digests of the content's lines
    triples_withheld: int | None = None  # triples of the post an erasure had removed, not recorded again

    def covered(self) -> dict[str, object]:
        """The fields the hash covers: every other one (the optional ones only where the receipt has them, so
        receipts from before they existed keep verifying)."""
        fields_ = {name: getattr(self, name) for name in _HASHED_FIELDS}
        for name in OPTIONAL_FIELDS:
            if fields_[name] is None:
                del fields_[name]
        return fields_

    def computed_hash(self) -> str:
        return receipt_hash(self.covered())

    def public(self) -> dict[str, object]:
        """The receipt as the API shows it: recomputing its hash from these keys gives `receipt_hash`."""
        return {**self.covered(), "receipt_hash": self.receipt_hash}

    def row(self) -> tuple[object, ...]:
        return tuple(getattr(self, name) for name in FIELD_NAMES)


FIELD_NAMES = tuple(field.name for field in fields(Receipt))
_HASHED_FIELDS = tuple(name for name in FIELD_NAMES if name != "receipt_hash")


def receipt_hash(covered: dict[str, object]) -> str:
    # Sorted keys and no spaces: the same receipt always hashes the same, whoever recomputes it.
    canonical = json.dumps(covered, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class BrokenLink:
    """The first receipt at which the chain fails, and why."""

    sequence: int
    log_id: str
    reason: BrokenReason


@dataclass(frozen=True)
class Verification:
    receipts: int
    first_broken: BrokenLink | None
    deep: bool = False
    redactions: int = 0  # erasures recorded in the chain

    @property
    def valid(self) -> bool:
        return self.first_broken is None


class ChainCheck:
    """Walks receipts oldest first and remembers the first fault."""

    def __init__(self) -> None:
        self.count = 0
        self.first_broken: BrokenLink | None = None
        self._expected_sequence = 1
        self._previous = GENESIS_HASH

    def add(self, receipt: Receipt, content_fault: BrokenReason | None = None) -> None:
        """Check one receipt; `content_fault` is what a deep check found wrong with its content, if anything."""
        self.count += 1
        if self.first_broken is None:
            reason = _fault(receipt, self._expected_sequence, self._previous) or content_fault
            if reason is not None:
                self.first_broken = BrokenLink(receipt.sequence, receipt.log_id, reason)
        self._expected_sequence, self._previous = receipt.sequence + 1, receipt.receipt_hash


def _fault(receipt: Receipt, expected_sequence: int, previous: str) -> BrokenReason | None:
    # A deleted receipt leaves a gap; an edited one no longer matches its own hash; a receipt whose hash
    # was recomputed after an edit no longer matches the next receipt's `previous_hash`.
    if receipt.sequence != expected_sequence:
        return "sequence gap"
    if receipt.computed_hash() != receipt.receipt_hash:
        return "hash mismatch"
    if receipt.previous_hash != previous:
        return "previous hash does not match"
    return None
