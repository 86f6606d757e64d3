"""A Turtle document as its prefix header and its blocks: the unit a robot's cumulative re-publish repeats.

The PyPI client serialises its whole graph with rdflib on every publish: the @prefix lines, then one block per
subject, blank lines between, the same bytes for the same triples under the same prefixes. So a re-publish is
mostly blocks sent before, byte for byte. Splitting on blank lines is only a guess at the document's structure
(a blank line may sit inside a long literal): what makes a block trustworthy is that it parses alone, after
the header, into complete statements with no directive of its own (`read_block`). A document whose blocks all
do is, statement for statement, those blocks; one whose blocks do not is parsed whole.
"""

from __future__ import annotations

import hashlib
import re
import sys
from dataclasses import dataclass
from itertools import islice

from pyoxigraph import BlankNode, Quad, RdfFormat, parse

from segb_server.backend.services.writing.journal import triple_digest
from segb_server.backend.store.terms import term_text

BOUNDARY = re.compile(rb"\n\n")
# A header line: a directive (Turtle's or SPARQL's), a comment, or blank.
HEADER_LINE = re.compile(rb"\s*(?:(?:@prefix|@base|prefix|base)\s|#|$)", re.IGNORECASE)
UTF8_BYTE_ORDER_MARK = b"\xef\xbb\xbf"
# A block's key is its 64-bit SipHash under this process's random key: no robot can aim a collision at it, and a
# changed block taken by chance for one of a 10,000-block graph's is about 5 in 10^16 (five new blocks a second:
# once in 10 million years). With PYTHONHASHSEED fixed the key is known: a cryptographic digest is used instead.
RANDOM_HASH = bool(sys.flags.hash_randomization)
Context = tuple[dict[str, str], str | None]  # prefixes and base IRI


@dataclass(frozen=True)
class Split:
    """A document cut at its blank lines: the header (directives only), then its blocks and their keys."""

    header: bytes
    blocks: list[bytes]
    keys: list[object]

    @property
    def context(self) -> bytes:
        """What a block's triples depend on besides its bytes: the prefixes and base the header declares."""
        return hashlib.blake2b(self.header, digest_size=16).digest()


@dataclass(frozen=True, slots=True)
class BlockFacts:
    """What a block parsed alone holds, as far as skipping it next time needs: how many distinct triples, the
    one subject they all share (its text's hash), and their digests (to check they were recorded)."""

    triples: int
    quads: int
    subject: int
    digests: tuple[bytes, ...]


def split_document(data: bytes) -> Split | None:
    """The document's header and blocks, or None when it has no blank line to cut at."""
    pieces = BOUNDARY.split(data.removeprefix(UTF8_BYTE_ORDER_MARK))
    if len(pieces) == 1:
        return None
    header = pieces[0] if _is_header(pieces[0]) else b""
    blocks = pieces[1:] if header else pieces
    if b"" in blocks:  # more than one blank line in a row: rare, so looked for before a copy is made
        blocks = [piece for piece in blocks if piece]
    return Split(header, blocks, block_keys(blocks))


def block_keys(blocks: list[bytes]) -> list[object]:
    """Each block's key among those one robot sent: its hash (a digest when hashes are predictable)."""
    if RANDOM_HASH:
        return list(map(hash, blocks))
    return [hashlib.blake2b(block, digest_size=16).digest() for block in blocks]


def read_block(header: bytes, block: bytes, context: Context) -> list[Quad] | None:
    """The block's triples parsed after the header, or None unless it is complete statements that declare no
    prefix or base of their own (`context`: the header's alone)."""
    parser = parse(header + b"\n\n" + block, RdfFormat.TURTLE)
    try:
        quads = list(parser)
    except (SyntaxError, MemoryError):
        return None
    return quads if (parser.prefixes, parser.base_iri) == context else None


def header_context(header: bytes) -> Context | None:
    """The prefixes and base the header declares, or None when it does not parse by itself."""
    parser = parse(header, RdfFormat.TURTLE)
    try:
        if list(islice(parser, 1)):  # a header states nothing
            return None
    except (SyntaxError, MemoryError):
        return None
    return dict(parser.prefixes), parser.base_iri


def facts_of(quads: list[Quad]) -> BlockFacts | None:
    """The facts to remember of a block, or None when it cannot be skipped: no triples, blank nodes (their
    names depend on the whole document), or more than one subject (two blocks could then share triples)."""
    if not quads:
        return None
    subject = quads[0].subject
    lines: dict[str, None] = {}
    for quad in quads:
        if quad.subject != subject or isinstance(quad.subject, BlankNode) or isinstance(quad.object, BlankNode):
            return None
        lines[f"{term_text(quad.subject)} {quad.predicate} {term_text(quad.object)}"] = None
    return BlockFacts(len(lines), len(quads), subject_hash(quad.subject), tuple(triple_digest(line) for line in lines))


def subject_hash(subject: object) -> int:
    return hash(term_text(subject))


def _is_header(text: bytes) -> bool:
    return all(HEADER_LINE.match(line) for line in text.split(b"\n"))
