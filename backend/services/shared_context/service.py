"""Resolving robots' observations to shared contexts, and the review of ambiguous ones.

Differences from the reference resolver, on purpose: the state is persisted (ContextState), URIs are
derived from the first observation (the same history always yields the same URIs), reviews are refreshed
after every write so reading the queue changes nothing, and every operation runs in one transaction, so
robots resolving the same event at once get one context.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.errors import Conflict, InvalidParameter, NotFound
from segb_server.backend.services.shared_context.policy import (
    MAX_CANDIDATES_PER_CASE,
    Policy,
    digest,
    scoring_text,
    slug,
)
from segb_server.backend.services.shared_context.scoring import Score, decisive, may_match, ranked, score
from segb_server.backend.services.shared_context.state import (
    Case,
    Context,
    ContextState,
    ObservationRow,
    observation_digest,
)
from segb_server.backend.state.database import Database

logger = logging.getLogger("segb.shared_context")


@dataclass(frozen=True)
class Observation:
    """A normalised resolve request (see policy.atom / policy.scoring_text)."""

    event_kind: str
    observed_at: float
    subject: str | None
    modality: str | None
    text: str | None
    canonical_text: str | None
    observation_uri: str | None = None
    robot_uri: str | None = None
    window: float | None = None
    reported_by: str | None = None


@dataclass(frozen=True)
class Resolution:
    shared_context_uri: str
    status: str  # created | matched | ambiguous
    confidence: float
    matched_candidate_uri: str | None
    close_candidates: list[str]
    score_breakdown: dict[str, float]
    candidate_count: int
    withheld: bool = False  # an observation a person's erasure removed, sent again: not recorded


@dataclass(frozen=True)
class Decision:
    case_id: str
    status: str
    source_context_uri: str
    selected_context_uri: str | None
    resulting_context_uri: str | None


@dataclass
class RefreshReport:
    scanned_ambiguous: int = 0
    mappings: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ContextRecord:
    context: Context
    observations: list[ObservationRow]


@dataclass(frozen=True)
class ReviewQueue:
    unresolved: list[ContextRecord]
    contexts: list[ContextRecord]  # every context a pending case or an unresolved context refers to
    pending_cases: list[Case]


class SharedContextService:
    def __init__(self, policy: Policy, state: ContextState) -> None:
        self.policy = policy
        self.state = state

    @classmethod
    def open(cls, policy: Policy, database: Database) -> SharedContextService:
        return cls(policy, ContextState(database))

    def close(self) -> None:
        self.state.close()

    # --- resolving -----------------------------------------------------------------------------------

    def resolve(self, observation: Observation) -> Resolution:
        window = observation.window or self.policy.time_window_seconds
        span = 2 * window
        with self.state.transaction() as state:
            if state.withheld(_digest_of(observation)):
                return self._withheld(state, observation)
            nearby = state.unmerged_near(
                observation.event_kind, observation.observed_at - span, observation.observed_at + span
            )
            scores = ranked(
                [
                    score(observation, context, context.uri, window)
                    for context in nearby
                    if may_match(observation, context, self.policy, span)
                ]
            )
            best = scores[0] if scores else None
            if best is not None and decisive(scores, self.policy):
                status, uri = "matched", self._absorb(state, best.context_uri, observation)
            else:
                ambiguous = best is not None and best.total >= self.policy.ambiguous_threshold
                status = "ambiguous" if ambiguous else "created"
                uri = self._create(state, observation, status="ambiguous" if ambiguous else "active")
            state.add_observation(_observation_row(uri, observation))
            self._refresh(state, observation.event_kind, observation.observed_at)
            if state.canonical(uri) != uri:  # the refresh merged the new context into an existing one
                status, uri = "matched", state.canonical(uri)
        return Resolution(
            shared_context_uri=uri,
            status=status,
            confidence=round(best.total, 4) if best else 0.0,
            matched_candidate_uri=best.context_uri if best else None,
            close_candidates=[found.context_uri for found in scores[:2]] if status == "ambiguous" else [],
            score_breakdown=_rounded(best.breakdown) if best else {},
            candidate_count=len(scores),
        )

    def _absorb(self, state: ContextState, uri: str, observation: Observation) -> str:
        context = state.context(uri)
        assert context is not None  # it was just found among the candidates, in this transaction
        # The anchor slides to the newest observation, as in the reference: a conversation drifts in time.
        context.observed_at = observation.observed_at
        context.subject = context.subject or observation.subject
        context.modality = context.modality or observation.modality
        context.canonical_text = context.canonical_text or observation.canonical_text
        context.updated_at = utc_iso()
        state.save_context(context)
        return uri

    def _withheld(self, state: ContextState, observation: Observation) -> Resolution:
        """Nothing recorded; the answer names the context this observation would make on its own (the URI it
        made before the erasure when it was the first of its context), so what the robot logs under it is the
        same again, and held back by the journal if it was erased too."""
        logger.warning("a shared-context observation removed by an erasure was sent again; it was not recorded")
        return Resolution(self._new_uri(state, observation), "created", 0.0, None, [], {}, 0, withheld=True)

    def _new_uri(self, state: ContextState, observation: Observation) -> str:
        """The first URI made from the observation that no context holds yet."""
        namespace = self.policy.namespace.rstrip("/")
        attempt = 0
        while True:
            basis = digest(
                observation.event_kind,
                utc_iso(observation.observed_at),
                observation.subject,
                observation.modality,
                observation.canonical_text,
                attempt,
            )
            uri = f"{namespace}/{slug(observation.event_kind)}_{basis[:16]}"
            if not state.uri_taken(uri):
                return uri
            attempt += 1

    def _create(self, state: ContextState, observation: Observation, status: str) -> str:
        uri = self._new_uri(state, observation)
        now = utc_iso()
        state.add_context(
            Context(
                None,
                uri,
                observation.event_kind,
                status,
                observation.observed_at,
                observation.subject,
                observation.modality,
                observation.canonical_text,
                now,
                now,
            )
        )
        return uri

    # --- review --------------------------------------------------------------------------------------

    def reconcile(self) -> tuple[RefreshReport, int]:
        with self.state.transaction() as state:
            report = self._refresh(state)
            return report, len(state.pending_cases())

    def review_queue(self) -> ReviewQueue:
        with self.state.snapshot() as state:
            cases = state.pending_cases()
            unresolved = state.with_status("ambiguous", newest_first=True)
            referred = [case.source_uri for case in cases] + [
                str(candidate["context_uri"]) for case in cases for candidate in case.candidates
            ]
            contexts = unresolved + state.contexts(referred)
            unique = {context.uri: context for context in contexts}.values()
            return ReviewQueue(
                unresolved=[self._record(state, context) for context in unresolved],
                contexts=[self._record(state, context) for context in sorted(unique, key=_recent_first, reverse=True)],
                pending_cases=cases,
            )

    def accept(self, case_id: str, target_uri: str) -> Decision:
        with self.state.transaction() as state:
            case = self._pending(state, case_id)
            target = state.canonical(target_uri.strip())
            offered = {state.canonical(str(candidate["context_uri"])) for candidate in case.candidates}
            if target == case.source_uri:
                raise InvalidParameter("target_context_uri", "source and target context cannot be the same")
            if target not in offered:
                raise InvalidParameter("target_context_uri", "is not one of this review case's candidates")
            self._merge(state, case.source_uri, target)
            self._refresh(state)
        return Decision(case_id, "accepted", case.source_uri, target, target)

    def reject(self, case_id: str) -> Decision:
        with self.state.transaction() as state:
            case = self._pending(state, case_id)
            for candidate in case.candidates:
                state.reject_pair(case.source_uri, str(candidate["context_uri"]))
            case.status, case.decided_at = "rejected", utc_iso()
            state.save_case(case)
        return Decision(case_id, "rejected", case.source_uri, None, None)

    def forget(self, iris: set[str], texts: set[str]) -> int:
        """An erasure: every context and observation naming one of `iris` or quoting one of `texts` goes (a
        context quotes a text as its scoring compares it: `scoring_text`)."""
        compared = {form for form in map(scoring_text, texts) if form is not None}
        with self.state.transaction() as state:
            removed = state.forget(iris, texts, compared)
        self.state.compact()
        return removed

    def forget_before(self, cutoff: str) -> int:
        """Retention: observations recorded before `cutoff` go, and contexts left without any."""
        with self.state.transaction() as state:
            removed = state.forget_before(cutoff)
        self.state.compact()
        return removed

    def stats(self) -> dict[str, int]:
        with self.state.snapshot() as state:
            counts = state.count_by_status()
            return {
                "active_contexts": counts.get("active", 0),
                "ambiguous_contexts": counts.get("ambiguous", 0),
                "merged_contexts": counts.get("merged", 0),
                "aliases": state.alias_count(),
                "pending_cases": len(state.pending_cases()),
            }

    def _pending(self, state: ContextState, case_id: str) -> Case:
        case = state.case(case_id)
        if case is None:
            raise NotFound(f"Review case '{case_id}' does not exist.")
        source = state.context(case.source_uri)
        if case.status != "pending" or source is None or source.status != "ambiguous":
            raise Conflict(f"Review case '{case_id}' is not pending (it is {case.status}).")
        return case

    def _refresh(
        self, state: ContextState, event_kind: str | None = None, around: float | None = None
    ) -> RefreshReport:
        """Merge ambiguous contexts that now have a decisive candidate; open or update cases for the rest.

        With `event_kind` and `around`, only the ambiguous contexts a change at that time can affect."""
        report = RefreshReport()
        if event_kind is None or around is None:
            sources = state.with_status("ambiguous")
        else:
            reach = 2 * self.policy.candidate_span
            sources = state.unmerged_near(event_kind, around - reach, around + reach, status="ambiguous")
        for source in sources:
            current = state.context(source.uri)
            if current is None or current.status != "ambiguous":
                continue  # merged into another earlier in this pass
            report.scanned_ambiguous += 1
            scores = self._review_scores(state, current)
            if decisive(scores, self.policy):
                self._merge(state, current.uri, scores[0].context_uri)
                report.mappings[current.uri] = scores[0].context_uri
            elif scores:
                self._open_case(state, current.uri, scores[:MAX_CANDIDATES_PER_CASE])
            else:
                self._close_case(state, current.uri, "rejected")
        return report

    def _review_scores(self, state: ContextState, source: Context) -> list[Score]:
        """Candidates for an ambiguous context, scored with the policy's window, without rejected pairs."""
        span = self.policy.candidate_span
        rejected = state.rejected_candidates(source.uri)
        nearby = state.unmerged_near(source.event_kind, source.observed_at - span, source.observed_at + span)
        scores = [
            _round(score(source, other, other.uri, self.policy.time_window_seconds))
            for other in nearby
            if other.uri != source.uri and other.uri not in rejected and may_match(source, other, self.policy, span)
        ]
        return [found for found in ranked(scores) if found.total >= self.policy.ambiguous_threshold]

    def _merge(self, state: ContextState, source_uri: str, target_uri: str) -> None:
        source, target = state.context(source_uri), state.context(target_uri)
        assert source is not None and target is not None
        now = utc_iso()
        state.add_alias(source_uri, target_uri)
        state.move_observations(source_uri, target_uri)
        source.status, source.updated_at = "merged", now
        target.status, target.updated_at = "active", now
        target.observed_at = max(source.observed_at, target.observed_at)
        target.subject = target.subject or source.subject
        target.modality = target.modality or source.modality
        target.canonical_text = target.canonical_text or source.canonical_text
        state.save_context(source)
        state.save_context(target)
        self._close_case(state, source_uri, "accepted", target_uri)

    def _open_case(self, state: ContextState, source_uri: str, scores: list[Score]) -> None:
        candidates = [
            {"context_uri": found.context_uri, "score": found.total, "score_breakdown": found.breakdown}
            for found in scores
        ]
        case = state.pending_case_of(source_uri)
        if case is None:
            case_id = "review_" + digest(source_uri, state.cases_of(source_uri))[:12]
            case = Case(case_id, source_uri, "pending", candidates, utc_iso())
        case.candidates = candidates
        state.save_case(case)

    def _close_case(self, state: ContextState, source_uri: str, status: str, selected: str | None = None) -> None:
        case = state.pending_case_of(source_uri)
        if case is not None:
            case.status, case.decided_at, case.selected_uri = status, utc_iso(), selected
            state.save_case(case)

    def _record(self, state: ContextState, context: Context) -> ContextRecord:
        return ContextRecord(context, state.observations(context.uri))


def _digest_of(observation: Observation) -> str:
    return observation_digest(
        observation.observed_at, observation.subject, observation.modality, observation.text,
        observation.observation_uri, observation.robot_uri,
    )  # fmt: skip


def _observation_row(uri: str, observation: Observation) -> ObservationRow:
    return ObservationRow(
        uri,
        observation.observed_at,
        observation.subject,
        observation.modality,
        observation.text,
        observation.observation_uri,
        observation.robot_uri,
        observation.reported_by,
        utc_iso(),
    )


def _round(found: Score) -> Score:
    return Score(found.context_uri, round(found.total, 4), _rounded(found.breakdown))


def _rounded(breakdown: dict[str, float]) -> dict[str, float]:
    return {term: round(value, 4) for term, value in breakdown.items()}


def _recent_first(context: Context) -> tuple[str, int]:
    return (context.updated_at, context.seq or 0)
