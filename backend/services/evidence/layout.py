"""What an evidence bundle holds, file by file: one home for the names and shapes the builder writes and the
verifier reads.

A bundle is a zip archive (it opens with a double click on every desktop system an investigator may use, and
Python's standard library reads it: the verifier needs nothing else but `cryptography`):

- `manifest.json`: who exported it, when, from which server, for which query; the chain head it reaches; the
  erasures in its range; the SHA-256 of every other file. `manifest.sig`: the server's Ed25519 signature of
  manifest.json's exact bytes (base64). `public-key.pem`: the key it was signed with (compare its fingerprint
  with the server's published one, or verify with `--public-key`).
- `triples.nt`: the window's triples exactly as the robots sent them (the journal's lines, lexical forms kept).
- `receipts.jsonl`: every receipt from the first one carrying a triple of the window to the chain's head, one JSON
  object per line: `{"receipt": …}` as GET /ledger shows it, plus `"redaction": …` (the record) for an erasure.
- `coverage.jsonl`: for each receipt carrying triples of the window, the lines it discloses and the SHA-256
  digests of its other lines (`withheld`) and of lines erasures removed (`redacted`): with them the receipt's
  `content_digest` is recomputed without the rest of its content.
- `timeline.html`: the window's events in time order, one self-contained page (no script, nothing fetched).
"""

from __future__ import annotations

FORMAT = "segb-evidence/1"
MANIFEST = "manifest.json"
SIGNATURE = "manifest.sig"
PUBLIC_KEY = "public-key.pem"
TRIPLES = "triples.nt"
RECEIPTS = "receipts.jsonl"
COVERAGE = "coverage.jsonl"
TIMELINE = "timeline.html"
SIGNED_FILES = (PUBLIC_KEY, TRIPLES, RECEIPTS, COVERAGE, TIMELINE)  # each one's SHA-256 is in the manifest
