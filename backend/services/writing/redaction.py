"""Redactions: what an erasure removed from posts' content, the record it leaves in the chain, and how redacted
content is verified. Pure standard library, so an offline verifier (an evidence bundle's) runs the same checks.

A post's receipt covers `content_digest`: the SHA-256 of its lines' SHA-256 digests, sorted. An erasure removes
lines from the content and keeps their digests beside it, so the remaining lines plus the kept digests still
give the digest the receipt covers: what remains provably was received, and nothing was added. The erasure's
own entry in the chain (its record) names, for each post it redacted, how many lines went and the SHA-256 of the
content that remains, so removing more lines later, or restoring some, breaks the deep verification.

An erasure of a person may put a line in place of one it removes: the same text with the person's names replaced
by a mark. Such a line was not received, so it is kept beside the post (its `replacements`), not in its content;
the record names, for each, the SHA-256 of the line removed and of the line put in its place, and the SHA-256 of
all the post's replacements, so they too are checked.

A kept digest confirms a guess of the exact line (subject, predicate and text) and tells nothing else.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

from segb_server.backend.services.writing.receipts import BrokenReason, Receipt

DIGEST_BYTES = 32


def line_digest(line: bytes) -> bytes:
    """A content line's digest (the line as the document holds it, ` .` included, without its newline)."""
    return hashlib.sha256(line).digest()


def lines_of(document: bytes) -> list[bytes]:
    return document.split(b"\n")[:-1] if document else []


def content_digest(document: bytes, redacted: bytes = b"") -> str:
    """The digest a post's receipt covers, from its content and the digests of the lines erased from it."""
    digests = [line_digest(line) for line in lines_of(document)]
    digests += [redacted[start : start + DIGEST_BYTES] for start in range(0, len(redacted), DIGEST_BYTES)]
    return hashlib.sha256(b"".join(sorted(digests))).hexdigest()


def canonical_json(value: object) -> bytes:
    """The one spelling of a JSON value every hash in the journal and in evidence bundles is taken over."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


@dataclass(frozen=True)
class Redacted:
    """What an erasure did to one post: the lines it removed, and the SHA-256 of the content that remains; when
    lines stand in for removed ones, the SHA-256 of them all and, per line it replaced, the SHA-256 of the line
    removed and of the one put in its place (a pair each)."""

    sequence: int
    log_id: str
    triples_removed: int
    remaining_sha256: str
    replacements_sha256: str | None = None
    replaced: list[tuple[str, str]] = field(default_factory=list)

    def document(self) -> dict[str, object]:
        """As the record holds it: without the replacements' fields when there are none, as erasures wrote it
        before they replaced lines (a record's hash is taken over this)."""
        found = asdict(self)
        if self.replacements_sha256 is None and not self.replaced:
            del found["replacements_sha256"], found["replaced"]
        else:
            found["replaced"] = [list(pair) for pair in self.replaced]
        return found


@dataclass(frozen=True)
class RedactionRecord:
    """An erasure's entry: why (its reason, typed by whoever erased), what kind (`human`: one person; `retention`:
    posts older than the retention period) and which posts lost how many lines. It names no person: the posts'
    numbers are enough to check it, and the record is kept for good."""

    kind: str
    reason: str
    receipts: list[Redacted] = field(default_factory=list)

    def document(self) -> bytes:
        return canonical_json(
            {"kind": self.kind, "reason": self.reason, "receipts": [item.document() for item in self.receipts]}
        )

    @classmethod
    def parse(cls, document: bytes) -> RedactionRecord:
        data = json.loads(document)
        return cls(data["kind"], data["reason"], [_redacted(item) for item in data["receipts"]])

    @property
    def triples_removed(self) -> int:
        return sum(item.triples_removed for item in self.receipts)


def _redacted(item: dict[str, Any]) -> Redacted:
    pairs = item.get("replaced") or []
    return Redacted(**{**item, "replaced": [(old, new) for old, new in pairs]})


@dataclass
class _State:
    removed: int = 0
    remaining_sha256: str = ""
    replacements_sha256: str | None = None
    records: list[int] = field(default_factory=list)


class RedactionCheck:
    """What the erasure records of a journal say of each post, to check its content against."""

    def __init__(self, records: Iterable[tuple[int, RedactionRecord]]) -> None:
        self.records = 0
        self._by_post: dict[int, _State] = {}
        for sequence, record in sorted(records, key=lambda pair: pair[0]):
            self.records += 1
            for item in record.receipts:
                state = self._by_post.setdefault(item.sequence, _State())
                state.removed += item.triples_removed
                state.remaining_sha256 = item.remaining_sha256  # the newest erasure says what is left
                state.replacements_sha256 = item.replacements_sha256
                state.records.append(sequence)

    def fault(
        self, receipt: Receipt, content: bytes, redacted: bytes, replacements: bytes = b""
    ) -> BrokenReason | None:
        """Whether the content kept for `receipt` (the digests of lines erased from it, and the lines put in
        place of some) is what its receipt and the erasure records say; None when it is."""
        state = self._by_post.get(receipt.sequence)
        content_sha256 = hashlib.sha256(content).hexdigest()
        replacements_sha256 = hashlib.sha256(replacements).hexdigest() if replacements else None
        if state is None:
            if redacted or replacements:
                return "redaction does not match"  # lines went, or came, without an erasure's record
            if receipt.content_sha256 not in (None, content_sha256):
                return "content does not match"
        else:
            if content_sha256 != state.remaining_sha256 or len(redacted) != state.removed * DIGEST_BYTES:
                return "redaction does not match"
            if replacements_sha256 != state.replacements_sha256:
                return "redaction does not match"
            if any(record <= receipt.sequence for record in state.records):
                return "redaction does not match"  # an erasure only ever redacts posts before it
        if receipt.content_digest is not None and content_digest(content, redacted) != receipt.content_digest:
            return "content does not match"
        return None
