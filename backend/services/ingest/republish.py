"""A cumulative re-publish read for what is new: blocks a robot's account sent before, and that were recorded,
are skipped before parsing, so the answer costs the new interaction, not the whole history.

A block is skipped only when all of this holds: the same account (and write scopes) sent the very same bytes
under the very same header, in the journal's current epoch (a clearing or an erasure starts a new one, in any
process, and the journal refuses a post read in an epoch that has ended: `EpochMoved`); it parsed alone into
complete statements about one subject, without blank nodes or directives; and every one of its triples was
recorded and none withheld. Everything else is parsed, and so is the whole document whenever a block it did not
skip does not parse alone: a syntax error is reported as it always was, with its line and column.

What is remembered is each block's key, its triple count and a hash of its subject: no triple's text, kept in
this process's memory only (rebuilt by an account's next post after a restart), bounded in blocks and accounts.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from operator import attrgetter

from pyoxigraph import Quad, RdfFormat

from segb_server.backend.services.errors import PayloadTooLarge
from segb_server.backend.services.ingest.blocks import (
    BlockFacts,
    Split,
    facts_of,
    header_context,
    read_block,
    split_document,
    subject_hash,
)
from segb_server.backend.services.ingest.parsing import parse_quads, refuse_triple_terms
from segb_server.backend.services.ingest.skolem import might_contain_blank_nodes

MAX_BLOCKS = 400_000  # remembered in all: about 75 MiB, 2.7M triples of the client's graphs (7 a block)
MAX_ACCOUNTS = 256
Account = tuple[str, tuple[str, ...]]  # who posts, with which write scopes


@dataclass
class Remembered:
    """An account's blocks known recorded, in one journal epoch, under one header."""

    epoch: int
    context: bytes
    blocks: dict[object, BlockFacts] = field(default_factory=dict)


@dataclass
class Reading:
    """A payload as read: the triples parsed, and what was skipped (triples counted, their subjects)."""

    quads: list[Quad]
    parsed: bytes  # the text the quads came from (blank nodes are looked for in it)
    held: int = 0  # distinct triples of the skipped blocks
    held_quads: int = 0  # triples as written in them (a block may state one twice)
    held_subjects: set[int] = field(default_factory=set)
    split: Split | None = None
    learned: dict[object, BlockFacts] = field(default_factory=dict)  # blocks read alone, to remember if recorded

    def overlaps(self, quads: list[Quad]) -> bool:
        """Whether a parsed triple has the subject of a skipped block (the counts could then share triples)."""
        return bool(self.held_subjects) and any(subject_hash(q.subject) in self.held_subjects for q in quads)


class BlockMemory:
    """The blocks each account sent that were recorded, least recently posting account forgotten first."""

    def __init__(self, max_blocks: int = MAX_BLOCKS, max_accounts: int = MAX_ACCOUNTS) -> None:
        self._accounts: OrderedDict[Account, Remembered] = OrderedDict()
        self._lock = threading.Lock()
        self._max_blocks, self._max_accounts = max_blocks, max_accounts

    def read(self, data: bytes, rdf_format: RdfFormat, account: Account, epoch: int, max_triples: int) -> Reading:
        """The payload's triples but those of blocks this account sent and had recorded in `epoch`."""
        split = split_document(data) if rdf_format == RdfFormat.TURTLE else None
        context = header_context(split.header) if split is not None else None
        if split is None or context is None:
            return _whole(data, rdf_format, max_triples)
        remembered = self._accounts.get(account)
        current = remembered is not None and (remembered.epoch, remembered.context) == (epoch, split.context)
        found = list(map(remembered.blocks.get, split.keys)) if remembered is not None and current else []
        reading = Reading([], b"", split=split)
        if not _held(reading, [facts for facts in found if facts is not None], max_triples):
            return _whole(data, rdf_format, max_triples)
        fresh = [index for index, facts in enumerate(found) if facts is None] if found else list(range(len(split.keys)))
        blocks = [split.blocks[index] for index in fresh]
        alone = [read_block(split.header, block, context) for block in blocks]
        if any(quads is None for quads in alone):  # not cut at statements' ends: the document is read whole
            return _whole(data, rdf_format, max_triples)
        for index, quads in zip(fresh, alone, strict=True):
            facts = facts_of(quads or [])
            if facts is not None:
                reading.learned[split.keys[index]] = facts
        if any(might_contain_blank_nodes(block) for block in blocks):
            # Blank node labels are the document's: the blocks not skipped are parsed together.
            reading.parsed = split.header + b"\n\n" + b"\n\n".join(blocks) if reading.held else data
            reading.quads = parse_quads(reading.parsed, rdf_format, max_triples=max_triples - reading.held)
        else:
            reading.quads = [quad for quads in alone for quad in quads or []]
            _refuse_past(max_triples, reading.held + len(reading.quads))
            refuse_triple_terms(reading.quads, rdf_format)
        return reading

    def recorded(
        self, reading: Reading, account: Account, epoch: int, withheld: int, holds: Callable[[Iterable[bytes]], bool]
    ) -> None:
        """The post read as `reading` was recorded in `epoch`: its blocks read alone are remembered, those with a
        withheld triple excepted (`holds`: whether the journal is known to hold these triples)."""
        split = reading.split
        if split is None or not reading.learned or len(split.keys) > self._max_blocks:
            return
        learned = {
            key: replace(facts, digests=())  # needed no longer: remembered without them
            for key, facts in reading.learned.items()
            if not withheld or holds(facts.digests)
        }
        with self._lock:
            remembered = self._accounts.pop(account, None)
            if remembered is None or (remembered.epoch, remembered.context) != (epoch, split.context):
                if remembered is not None and remembered.epoch > epoch:
                    self._accounts[account] = remembered  # a later post already remembers a later epoch's
                    return
                remembered = Remembered(epoch, split.context)
            remembered.blocks.update(learned)
            if len(remembered.blocks) > 2 * len(split.keys) + 64:  # blocks the robot no longer sends
                sent = set(split.keys)
                remembered.blocks = {key: facts for key, facts in remembered.blocks.items() if key in sent}
            self._accounts[account] = remembered
            self._bound()

    def forget(self) -> None:
        """Forget every account's blocks (their next posts are read whole)."""
        with self._lock:
            self._accounts.clear()

    def _bound(self) -> None:
        total = sum(len(remembered.blocks) for remembered in self._accounts.values())
        while self._accounts and (total > self._max_blocks or len(self._accounts) > self._max_accounts):
            _, oldest = self._accounts.popitem(last=False)
            total -= len(oldest.blocks)


def _held(reading: Reading, held: list[BlockFacts], max_triples: int) -> bool:
    """Count the skipped blocks into `reading`; False when two share a subject (their triples could overlap)."""
    reading.held_subjects = set(map(attrgetter("subject"), held))
    if len(reading.held_subjects) < len(held):
        return False
    reading.held, reading.held_quads = sum(map(attrgetter("triples"), held)), sum(map(attrgetter("quads"), held))
    _refuse_past(max_triples, reading.held)
    return True


def _refuse_past(max_triples: int, triples: int) -> None:
    if triples > max_triples:
        raise PayloadTooLarge(f"The payload has more than {max_triples} triples (MAX_TRIPLES_PER_POST).")


def _whole(data: bytes, rdf_format: RdfFormat, max_triples: int) -> Reading:
    return Reading(parse_quads(data, rdf_format, max_triples=max_triples), data)
