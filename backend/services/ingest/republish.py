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
from itertools import compress
from operator import not_

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


@dataclass(frozen=True)
class Remembered:
    """An account's blocks known recorded, in one journal epoch, under one header: one block a subject (a
    subject's new block replaces its old one), their triples counted in all. Replaced whole on every change, so
    a post reading it holds one consistent state without taking the lock."""

    epoch: int
    context: bytes
    blocks: dict[object, BlockFacts] = field(default_factory=dict)
    subjects: dict[int, object] = field(default_factory=dict)  # a block's subject (its hash) → its key
    triples: int = 0  # distinct triples of all the blocks
    quads: int = 0  # triples as written in them

    @classmethod
    def of(cls, epoch: int, context: bytes, blocks: dict[object, BlockFacts]) -> Remembered:
        return cls(epoch, context).with_blocks(blocks)

    def with_blocks(self, learned: dict[object, BlockFacts]) -> Remembered:
        blocks, subjects = dict(self.blocks), dict(self.subjects)
        triples, quads = self.triples, self.quads
        for key, facts in learned.items():
            if key in blocks:
                continue
            replaced = subjects.get(facts.subject)
            if replaced is not None:  # the subject's block changed: its old bytes would repeat its triples
                old = blocks.pop(replaced)
                triples, quads = triples - old.triples, quads - old.quads
            blocks[key], subjects[facts.subject] = facts, key
            triples, quads = triples + facts.triples, quads + facts.quads
        return Remembered(self.epoch, self.context, blocks, subjects, triples, quads)


@dataclass(frozen=True)
class HeldSubjects:
    """The subjects of the blocks a post re-sent and had skipped: the remembered ones but those it left out."""

    subjects: dict[int, object]
    left_out: set[object]

    def __contains__(self, subject: object) -> bool:
        key = self.subjects.get(subject) if isinstance(subject, int) else None
        return key is not None and key not in self.left_out


@dataclass
class Reading:
    """A payload as read: the triples parsed, and what was skipped (triples counted, their subjects)."""

    quads: list[Quad]
    parsed: bytes  # the text the quads came from (blank nodes are looked for in it)
    held: int = 0  # distinct triples of the skipped blocks
    held_quads: int = 0  # triples as written in them (a block may state one twice)
    held_subjects: HeldSubjects | None = None
    split: Split | None = None
    learned: dict[object, BlockFacts] = field(default_factory=dict)  # blocks read alone, to remember if recorded

    def overlaps(self, quads: list[Quad]) -> bool:
        """Whether a parsed triple has the subject of a skipped block (the counts could then share triples)."""
        held = self.held_subjects
        return held is not None and any(subject_hash(q.subject) in held for q in quads)


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
        reading = Reading([], b"", split=split)
        if remembered is None or (remembered.epoch, remembered.context) != (epoch, split.context):
            fresh = list(range(len(split.keys)))
        elif (unknown := _held(reading, remembered, max_triples)) is None:
            return _whole(data, rdf_format, max_triples)
        else:
            fresh = unknown
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
            remembered = remembered.with_blocks(learned)
            if len(remembered.blocks) > 2 * len(split.keys) + 64:  # blocks the robot no longer sends
                sent = set(split.keys)
                kept = {key: facts for key, facts in remembered.blocks.items() if key in sent}
                remembered = Remembered.of(epoch, split.context, kept)
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


def _held(reading: Reading, remembered: Remembered, max_triples: int) -> list[int] | None:
    """Count the remembered blocks the post re-sent into `reading` as skipped; the indexes of the blocks it did
    not, or None when it sends a remembered block twice (the document is then read whole). Done with a mask and
    set operations, never a loop over the blocks: a re-publish holds tens of thousands."""
    keys = reading.split.keys if reading.split is not None else []
    fresh = list(compress(range(len(keys)), map(not_, map(remembered.blocks.__contains__, keys))))
    sent = set(keys)
    if len(sent) - len({keys[index] for index in fresh}) < len(keys) - len(fresh):
        return None  # a remembered block sent twice
    # Blocks the robot changed since, or no longer sends: most re-publishes leave out none.
    left_out = set() if len(keys) - len(fresh) == len(remembered.blocks) else remembered.blocks.keys() - sent
    gone = [remembered.blocks[key] for key in left_out]
    reading.held = remembered.triples - sum(facts.triples for facts in gone)
    reading.held_quads = remembered.quads - sum(facts.quads for facts in gone)
    reading.held_subjects = HeldSubjects(remembered.subjects, left_out) if reading.held else None
    _refuse_past(max_triples, reading.held)
    return fresh


def _refuse_past(max_triples: int, triples: int) -> None:
    if triples > max_triples:
        raise PayloadTooLarge(f"The payload has more than {max_triples} triples (MAX_TRIPLES_PER_POST).")


def _whole(data: bytes, rdf_format: RdfFormat, max_triples: int) -> Reading:
    return Reading(parse_quads(data, rdf_format, max_triples=max_triples), data)
