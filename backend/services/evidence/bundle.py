"""Making an evidence bundle: the window's resources found in the store (`sparql/evidence/window.rq`), their
triples read from the journal exactly as received, the receipts carrying them and the chain from the first of
those to the head, all signed by the server's key (layout.py says what each file is)."""

from __future__ import annotations

import base64
import hashlib
import io
import json
import socket
import zipfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

from segb_server.backend import __version__
from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.evidence import layout
from segb_server.backend.services.evidence.key import ServerKey
from segb_server.backend.services.evidence.timeline_page import render_timeline
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.values import json_value
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.redaction import (
    DIGEST_BYTES,
    RedactionRecord,
    canonical_json,
    line_digest,
    lines_of,
)
from segb_server.backend.store.base import Store, select

WINDOW = "evidence/window"


@dataclass
class _Coverage:
    """One receipt's share of the window: the lines it discloses, the digests of the rest."""

    sequence: int
    disclosed: list[bytes] = field(default_factory=list)
    withheld: list[str] = field(default_factory=list)
    redacted: list[str] = field(default_factory=list)

    def line(self) -> bytes:
        return canonical_json(
            {
                "sequence": self.sequence,
                "disclosed": [line.decode("utf-8") for line in self.disclosed],
                "withheld": self.withheld,
                "redacted": self.redacted,
            }
        )


@dataclass(frozen=True)
class Bundle:
    data: bytes
    triples: int
    receipts: int
    head: int


class EvidenceService:
    def __init__(self, store: Store, journal: Journal, window: CatalogQuery, key: ServerKey) -> None:
        self.store = store
        self.journal = journal
        self.window = window
        self.key = key

    def build(self, filters: Mapping[str, str | None], exported_by: str) -> Bundle:
        """The bundle of the window `filters` name (robot, since, until; blocking)."""
        bound = self.window.bindings(filters)  # 422 naming a bad value
        rows = [{k: json_value(v) for k, v in row.items()} for row in select(self.store, self.window.text, bound).rows]
        items = {f"<{row['item']}>".encode() for row in rows if isinstance(row.get("item"), str)}
        coverage = list(self._coverage(items))
        head = self.journal.head()
        first = coverage[0].sequence if coverage else head
        receipts = list(self.journal.receipts_after(first - 1)) if head else []
        records = {receipt.sequence: record for receipt, record in self.journal.redaction_records()}
        files = {
            layout.PUBLIC_KEY: self.key.public_pem(),
            layout.TRIPLES: b"".join(line + b"\n" for line in dict.fromkeys(x for c in coverage for x in c.disclosed)),
            layout.RECEIPTS: b"".join(_receipt_line(r, records.get(r.sequence)) + b"\n" for r in receipts),
            layout.COVERAGE: b"".join(c.line() + b"\n" for c in coverage),
            layout.TIMELINE: render_timeline(_title(filters), rows).encode("utf-8"),
        }
        carried = {c.sequence for c in coverage}
        manifest = {
            "format": layout.FORMAT,
            "exported_at": utc_iso(),
            "exported_by": exported_by,
            "server": {"host": socket.gethostname(), "version": __version__, "key_fingerprint": self.key.fingerprint},
            "query": {name: filters.get(name) for name in ("robot", "since", "until")},
            "window": {"events": len(rows), "triples": files[layout.TRIPLES].count(b"\n"), "receipts": len(coverage)},
            "chain": {
                "from": receipts[0].sequence if receipts else None,
                "head": {"sequence": receipts[-1].sequence, "receipt_hash": receipts[-1].receipt_hash}
                if receipts
                else None,
            },
            "redactions": [
                _redaction(receipt, records[receipt.sequence], carried)
                for receipt in receipts
                if receipt.sequence in records
            ],
            "files": {name: hashlib.sha256(data).hexdigest() for name, data in files.items()},
        }
        manifest_bytes = json.dumps(manifest, indent=2, ensure_ascii=False).encode("utf-8")
        archive = io.BytesIO()
        with zipfile.ZipFile(archive, "w", compression=zipfile.ZIP_DEFLATED) as bundle:
            bundle.writestr(layout.MANIFEST, manifest_bytes)
            bundle.writestr(layout.SIGNATURE, base64.b64encode(self.key.sign(manifest_bytes)) + b"\n")
            for name, data in files.items():
                bundle.writestr(name, data)
        return Bundle(archive.getvalue(), manifest["window"]["triples"], len(receipts), head)  # type: ignore[index]

    def _coverage(self, items: set[bytes]) -> Iterator[_Coverage]:
        """Each post holding a line about one of `items` (its subject), with what it discloses and the digests of
        the rest. A post from before content digests existed discloses all it holds (only its whole content can
        be checked against its receipt)."""
        if not items:
            return
        for receipt, content, redacted in self.journal.posts_since_clearing():
            lines = lines_of(content)
            about = [line for line in lines if line.partition(b" ")[0] in items]
            if not about:
                continue
            if receipt.content_digest is None:
                about = lines
            chosen = set(about)
            yield _Coverage(
                receipt.sequence,
                about,
                [line_digest(line).hex() for line in lines if line not in chosen],
                [redacted[i : i + DIGEST_BYTES].hex() for i in range(0, len(redacted), DIGEST_BYTES)],
            )


def _receipt_line(receipt: Receipt, record: RedactionRecord | None) -> bytes:
    entry: dict[str, object] = {"receipt": receipt.public()}
    if record is not None:
        entry["redaction"] = json.loads(record.document())
    return canonical_json(entry)


def _redaction(receipt: Receipt, record: RedactionRecord, carried: set[int]) -> dict[str, object]:
    """What the manifest says of an erasure in the bundle's range: who, when, why, how much, and which of the
    bundle's receipts lost lines to it."""
    posts = [item.sequence for item in record.receipts]
    return {
        "sequence": receipt.sequence,
        "log_id": receipt.log_id,
        "recorded_at": receipt.recorded_at,
        "user": receipt.user,
        "kind": record.kind,
        "reason": record.reason,
        "triples_removed": receipt.triples_removed,
        "receipts_in_window": sorted(set(posts) & carried),
    }


def _title(filters: Mapping[str, str | None]) -> str:
    robot = filters.get("robot") or "every robot"
    return f"{robot}, {filters.get('since') or 'the beginning'} to {filters.get('until') or 'now'}"
