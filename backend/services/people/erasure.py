"""Erasing one person (GDPR Art. 17), and retention's erasure of old posts, through the journal.

What goes with a person is the rule `sparql/people/erase.rq` (docs/personal-data.md explains it), of which only
what concerns that person is kept (reach.py: never another agent, a class or a predicate), and only for an IRI the
log types as a person. The resources it names are found in the store once it holds the whole journal; every line
of every post whose subject or object is one of them leaves the journal's content in one transaction that also
appends the erasure's record (writing/erasure.py), and later posts naming them are withheld; the applier then
removes those triples from the store, the views' keeper builds every view again from the store, and the other
places that hold data let the person go too (`Forgetting`).
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, field

from pyoxigraph import Literal, NamedNode, RdfFormat, parse

from segb_server.backend.services.errors import Conflict, InvalidParameter, NotFound
from segb_server.backend.services.people.mentions import Mentions, Scope, mentions, names_of, still_mentioned
from segb_server.backend.services.people.reach import (
    check_erasable,
    check_person_types,
    kinds,
    reach,
    standing,
    triples_about,
)
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.writing.erasure import (
    Erasure,
    ErasureDone,
    SelectionOutdated,
    recorded_before,
    touching,
)
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.write_path import WritePath
from segb_server.backend.store.base import Store, StoreUnavailable

logger = logging.getLogger("segb.people")

RULE = "people/erase"
APPLY_TIMEOUT_SECONDS = 600.0  # an erasure is answered once the store has dropped the triples
# Times the rule runs when posts about the person arrive while it runs (each may hold more of theirs to erase):
# from the second on, this process's posts wait until the erasure is recorded, so only other processes' posts
# (API workers, hosts) can race it; past the last the erasure is refused, nothing recorded, rather than leave
# their newest words behind.
FIND_ATTEMPTS = 5
# While this process's posts are held, the store gets this long to apply what the journal took before them: a
# store gone away must not hold posts up for long (with INGEST_ACK=journal they are taken while it is away).
HELD_APPLY_TIMEOUT_SECONDS = 30.0
MAX_REASON = 500
SHORTEST_TERM = 3  # words shorter than this are too common to look for in the server log


@dataclass(frozen=True)
class Forgotten:
    """What an erasure removed, for the places outside the store and the journal: the IRIs it erased and the
    texts (names, sentences) of the literals it removed; for retention, the time before which all went."""

    iris: frozenset[str] = frozenset()
    texts: frozenset[str] = frozenset()
    before: str | None = None


@dataclass
class Forgetting:
    """The places besides the store and the journal that hold what robots logged: each is told what went.
    `now`: once the store has applied the erasure; `after_views`: once the views are built again."""

    now: list[Callable[[Forgotten], object]] = field(default_factory=list)
    after_views: list[Callable[[Forgotten], object]] = field(default_factory=list)


@dataclass(frozen=True)
class ErasureResult:
    receipt: Receipt
    receipts_redacted: int
    resources: int
    views_rebuilt: bool
    # Texts kept with the person's names replaced by the mark (mentions.py), and literals that still hold one of
    # their names afterwards (what concerns someone else, unless the erasure was store-wide): whoever erases
    # should know what remains.
    mentions_redacted: int = 0
    name_still_mentioned: int = 0
    seconds: dict[str, float] = field(default_factory=dict)  # how long each step took (found, journaled, …)


@dataclass(frozen=True)
class ErasurePreview:
    """What erasing a person would take, found in the store and written nowhere: the resources by kind, the
    triples of the store that name one of them, and how many resources the rule reached but would leave alone (an
    agent, a class or a predicate a robot linked to the person's resources, or reached only through one)."""

    human: str
    resources: int
    kinds: dict[str, int]
    triples: int
    left_out: int
    mentions: int = 0  # texts kept that would have the person's names replaced by the mark


class ErasureService:
    """One erasure at a time (they are rare, and each rewrites the store's files on the embedded store)."""

    def __init__(
        self,
        store: Store,
        rule: CatalogQuery,
        writes: WritePath,
        forgetting: Forgetting,
        *,
        mentions_rule: CatalogQuery,
        views_timeout: float = 120.0,
    ) -> None:
        self.store = store
        self.rule = rule
        self.mentions_rule = mentions_rule
        self.writes = writes
        self.forgetting = forgetting
        self.views_timeout = views_timeout
        self._one_at_a_time = threading.Lock()

    def resources(self, human: str) -> list[str]:
        """The IRIs the rule erases with `human`, found in the store (blocking)."""
        return reach(self.store, self.rule, human).resources

    def check_person(self, human: str) -> None:
        """422 when the log types `human` and as something else than a person (a robot, a model, a message): an
        export would tell a robot's log as someone's life. An IRI the log does not type passes here (a robot may
        name someone without typing them): only an erasure, which cannot be undone, asks for a person's type."""
        check_person_types(human, standing(self.store, [human])[human].types)

    def preview(self, human: str, scope: Scope = "concerning") -> ErasurePreview:
        """What erasing `human` would take, as the store holds it now; nothing is written (blocking). 404 and 422
        as for the erasure itself."""
        check_erasable(self.store, human)
        found = reach(self.store, self.rule, human)
        triples = len(set(triples_about(self.store, found.resources)))
        texts = len(self._mentions(human, found.resources, scope))
        return ErasurePreview(
            human, len(found.resources), kinds(self.store, found.resources), triples, found.left_out, texts
        )

    def erase_human(self, human: str, reason: str, actor: str, scope: Scope = "concerning") -> ErasureResult:
        """Erase `human` everywhere, their names replaced by the mark in the texts kept that concern them (or, with
        `scope` "store", in every text); 404 when neither the store nor the journal holds anything about them,
        422 when the log does not type them as a person."""
        reason = _checked_reason(reason)
        with self._one_at_a_time:
            clock = _Clock()
            found, redacting, done = self._found_and_journaled(human, reason, actor, scope, clock)
            receipt = done.receipt
            forgotten = Forgotten(frozenset(found), frozenset(_texts(done.removed)))
            logger.warning(
                "erasure log_id=%s actor=%s kind=human resources=%d triples=%d texts_redacted=%d",
                receipt.log_id, actor, len(found), receipt.triples_removed, len(redacting),
            )  # fmt: skip
            rebuilt = self._forget(receipt, forgotten, clock)
            left = still_mentioned(self.store, redacting.names)
            clock.lap("checked")
            return ErasureResult(receipt, done.posts, len(found), rebuilt, len(redacting), left, clock.laps)

    def erase_before(self, cutoff: str, reason: str, actor: str) -> ErasureResult | None:
        """Retention: every post recorded before `cutoff` loses its content; None when none had any."""
        with self._one_at_a_time:
            erasure = Erasure(str(uuid.uuid4()), actor, "retention", reason, recorded_before(cutoff), withhold=False)
            try:
                done = self._journal(erasure, "")
            except NotFound:
                return None
            receipt = done.receipt
            clock = _Clock()
            logger.warning("erasure log_id=%s kind=retention before=%s triples=%d", receipt.log_id, cutoff,
                           receipt.triples_removed)  # fmt: skip
            rebuilt = self._forget(receipt, Forgotten(before=cutoff), clock)
            return ErasureResult(receipt, done.posts, 0, rebuilt, seconds=clock.laps)

    # --- steps ---------------------------------------------------------------------------------------

    def _found_and_journaled(
        self, human: str, reason: str, actor: str, scope: Scope, clock: _Clock
    ) -> tuple[list[str], Mentions, ErasureDone]:
        """What the rule erases with `human`, found in the store as of an entry, and the erasure recorded with
        nothing recorded after that entry touching it: a post about them that arrived while the rule ran may
        hold a message of theirs the rule has not seen, so the rule runs again (Conflict when that keeps
        happening)."""
        for attempt in range(1, FIND_ATTEMPTS + 1):
            # The first run holds no post up; once one raced it, the next runs keep this process's posts waiting.
            held = attempt > 1
            with self.writes.journal.posts_held() if held else nullcontext():
                as_of = self._caught_up(HELD_APPLY_TIMEOUT_SECONDS if held else APPLY_TIMEOUT_SECONDS)
                check_erasable(self.store, human)
                found = self.resources(human)
                clock.lap("found")
                if human not in found:
                    found.append(human)  # the journal may still hold them (a post not applied, an older history)
                redacting = self._mentions(human, found, scope)
                selection = touching(found).either(redacting.selection())
                erasure = Erasure(
                    str(uuid.uuid4()), actor, "human", reason, selection, withhold=True, found_as_of=as_of,
                    resources=frozenset(found),
                )  # fmt: skip
                try:
                    done = self._journal(erasure, f"Nothing about <{human}> is held: nothing was erased.")
                except SelectionOutdated as outdated:
                    logger.info("erasure of a person: %s; finding what to erase again (attempt %d)", outdated, attempt)
                    continue
            clock.lap("journaled")
            return found, redacting, done
        raise Conflict(
            f"Posts about <{human}> kept arriving while the erasure looked for what to erase ({FIND_ATTEMPTS} "
            "times): nothing was erased. Pause the robots that log this person, then erase again."
        )

    def _caught_up(self, timeout: float) -> int:
        """The entry through which the store holds the journal (the rule reads it), or StoreUnavailable."""
        self._apply()
        head = self.writes.journal.head()
        if not self.writes.wait_applied(head, timeout):
            raise StoreUnavailable("the store has not applied the journal yet; the erasure was not started")
        return head

    def _journal(self, erasure: Erasure, nothing: str) -> ErasureDone:
        done = self.writes.journal.append_erasure(erasure)
        if done is None:
            raise NotFound(nothing)
        return done

    def _forget(self, receipt: Receipt, forgotten: Forgotten, clock: _Clock) -> bool:
        """Once the store applied the erasure, the other places forget too; True when the views were built again
        within the wait (otherwise the places that follow them forget once they are)."""
        self._apply()
        if not self.writes.wait_applied(receipt.sequence, APPLY_TIMEOUT_SECONDS):
            raise StoreUnavailable(
                f"the erasure is recorded (log_id {receipt.log_id}) and the store will apply it when it answers"
            )
        clock.lap("applied")
        for forget in self.forgetting.now:
            forget(forgotten)
        clock.lap("forgotten")
        if self.writes.wait_viewed(receipt.sequence, self.views_timeout):
            clock.lap("viewed")
            for forget in self.forgetting.after_views:
                forget(forgotten)
            clock.lap("views_compacted")
            return True
        threading.Thread(target=self._after_views, args=(receipt, forgotten), daemon=True).start()
        return False

    def _mentions(self, human: str, resources: list[str], scope: Scope) -> Mentions:
        """The texts kept that hold one of `human`'s names: those that concern them, or every one (`scope`
        "store"); not those of the resources erased whole."""
        found = mentions(self.store, self.mentions_rule, human, names_of(self.store, human), scope)
        erased = {NamedNode(iri) for iri in resources}
        return Mentions(found.names, frozenset(t for t in found.triples if t.subject not in erased))

    def _apply(self) -> None:
        """Apply what is pending in this thread where this process applies (a command-line erasure has no
        applier thread); the applier's thread would otherwise take it."""
        self.writes.entries_written()
        self.writes.apply_now()

    def _after_views(self, receipt: Receipt, forgotten: Forgotten) -> None:
        while not self.writes.wait_viewed(receipt.sequence, self.views_timeout):
            logger.info("erasure log_id=%s: the views are still being built", receipt.log_id)
        for forget in self.forgetting.after_views:
            forget(forgotten)


class _Clock:
    def __init__(self) -> None:
        self.laps: dict[str, float] = {}
        self._last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = round(now - self._last, 3)
        self._last = now


def _checked_reason(reason: str) -> str:
    reason = " ".join(reason.split())
    if not reason:
        raise InvalidParameter("reason", "say why (it is kept in the ledger for good; do not name the person)")
    if len(reason) > MAX_REASON:
        raise InvalidParameter("reason", f"at most {MAX_REASON} characters")
    return reason


FIRST_NAME = "http://xmlns.com/foaf/0.1/firstName"


def _texts(lines: list[bytes]) -> set[str]:
    """The text of every literal among the removed lines (what the server log might quote)."""
    if not lines:
        return set()
    found = {
        quad.object.value
        for quad in parse(b"".join(line + b"\n" for line in lines), RdfFormat.N_TRIPLES)
        if isinstance(quad.object, Literal)
    }
    return {text for text in found if len(text) >= SHORTEST_TERM}
