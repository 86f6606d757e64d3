"""/shared-context: robots resolve an observed event to one shared URI; admins review the ambiguous ones.

Compatible with `HTTPSharedContextResolver` of the PyPI `semantic-log-generator` (it reads only
`shared_context_uri`) and with the reference backend's review endpoints.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict
from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, Path
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, Field, field_validator

from segb_server.backend.api.deps import Admin, Auditor, Publisher, ServicesDep
from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.errors import Conflict, InvalidParameter, NotFound
from segb_server.backend.services.shared_context.policy import RESOLVER_VERSION, atom, epoch, scoring_text
from segb_server.backend.services.shared_context.service import ContextRecord, Decision, Observation
from segb_server.backend.services.shared_context.state import Case
from segb_server.backend.services.sparql.catalog import is_absolute_iri
from segb_server.backend.services.text import UnicodeModel

router = APIRouter(prefix="/shared-context", tags=["shared context"])

MAX_TEXT = 4096  # scoring compares texts pairwise; a bound keeps one resolve cheap
MAX_ATOM = 2048


class ResolveRequest(UnicodeModel):
    event_kind: str = Field(max_length=MAX_ATOM, examples=["human_utterance"])
    observed_at: datetime = Field(description="ISO 8601; a time without offset is taken as UTC.")
    subject_uri: str | None = Field(None, max_length=MAX_ATOM)
    modality: str | None = Field(None, max_length=MAX_ATOM, examples=["speech"])
    text: str | None = Field(None, max_length=MAX_TEXT, examples=["Hello robot"])
    observation_uri: str | None = Field(None, max_length=MAX_ATOM)
    robot_uri: str | None = Field(None, max_length=MAX_ATOM)
    time_window_seconds: float | None = Field(
        None, ge=0, le=86400, allow_inf_nan=False, description="0 or absent = the server's."
    )

    @field_validator("event_kind")
    @classmethod
    def _not_blank(cls, value: str) -> str:
        if not value.strip():
            raise ValueError("must be a non-empty string")
        return value

    @field_validator("subject_uri", "observation_uri", "robot_uri")
    @classmethod
    def _absolute_iri(cls, value: str | None) -> str | None:
        # They name resources of the log (and come back in answers and pages): an IRI as the log's, or nothing.
        if value is not None and value.strip() and not is_absolute_iri(value.strip()):
            raise ValueError("must be an absolute IRI (http://, https:// or urn:)")
        return value

    def observation(self, reported_by: str) -> Observation:
        return Observation(
            event_kind=atom(self.event_kind) or "",
            observed_at=epoch(self.observed_at),
            subject=atom(self.subject_uri),
            modality=atom(self.modality),
            text=(self.text or "").strip() or None,
            canonical_text=scoring_text(self.text),
            observation_uri=(self.observation_uri or "").strip() or None,
            robot_uri=(self.robot_uri or "").strip() or None,
            window=self.time_window_seconds or None,
            reported_by=reported_by,
        )


class Versioned(BaseModel):
    resolver_version: str = RESOLVER_VERSION


class ResolveResponse(Versioned):
    shared_context_uri: str = Field(description="The canonical URI to log the observation under.")
    status: Literal["created", "matched", "ambiguous"]
    confidence: float = Field(description="Score of the best candidate (0 when there was none).")
    matched_candidate_uri: str | None
    close_candidates: list[str] = Field(description="For `ambiguous`: the best two candidates.")
    score_breakdown: dict[str, float] = Field(description="The best candidate's time/subject/modality/text terms.")
    candidate_count: int
    withheld: bool = Field(
        False,
        description="The observation was removed by a person's erasure and is sent again: it is not recorded, and "
        "the URI is the one it would make on its own (see docs/personal-data.md).",
    )


class ObservationOut(BaseModel):
    observed_at: str
    subject_uri: str | None
    modality: str | None
    text: str | None
    observation_uri: str | None
    robot_uri: str | None
    reported_by: str | None


class ContextOut(BaseModel):
    uri: str
    event_kind: str
    status: Literal["active", "ambiguous", "merged"]
    observed_at: str
    subject_uri: str | None
    modality: str | None
    canonical_text: str | None
    observation_count: int
    observations: list[ObservationOut] = Field(description="Newest first.")

    @classmethod
    def of(cls, record: ContextRecord) -> ContextOut:
        context = record.context
        return cls(
            uri=context.uri,
            event_kind=context.event_kind,
            status=context.status,
            observed_at=utc_iso(context.observed_at),
            subject_uri=context.subject,
            modality=context.modality,
            canonical_text=context.canonical_text,
            observation_count=len(record.observations),
            observations=[
                ObservationOut(**{**asdict(row), "observed_at": utc_iso(row.observed_at), "subject_uri": row.subject})
                for row in record.observations
            ],
        )


class CandidateOut(BaseModel):
    context_uri: str
    score: float
    score_breakdown: dict[str, float]


class CaseOut(BaseModel):
    case_id: str
    source_context_uri: str
    candidates: list[CandidateOut]
    status: Literal["pending", "accepted", "rejected"]
    created_at: str
    decided_at: str | None
    selected_context_uri: str | None

    @classmethod
    def of(cls, case: Case) -> CaseOut:
        return cls(**asdict(case), source_context_uri=case.source_uri, selected_context_uri=case.selected_uri)


class ReviewQueueOut(Versioned):
    unresolved_count: int
    pending_count: int
    unresolved_contexts: list[ContextOut] = Field(description="Ambiguous contexts, most recently updated first.")
    contexts: list[ContextOut] = Field(
        description="Every context the unresolved ones and the pending cases refer to, most recently updated first."
    )
    pending_cases: list[CaseOut] = Field(description="Newest first.")


class ReconcileOut(Versioned):
    scanned_ambiguous: int
    merged_count: int
    mappings: dict[str, str] = Field(description="Merged source URI → the context it now resolves to.")
    pending_cases: int


class DecisionOut(Versioned):
    case_id: str
    status: Literal["accepted", "rejected"]
    source_context_uri: str
    selected_context_uri: str | None
    resulting_context_uri: str | None

    @classmethod
    def of(cls, decision: Decision) -> DecisionOut:
        return cls(**asdict(decision))


class AcceptRequest(UnicodeModel):
    target_context_uri: str = Field(min_length=1, max_length=MAX_ATOM)


class StatsOut(Versioned):
    active_contexts: int
    ambiguous_contexts: int
    merged_contexts: int
    aliases: int
    pending_cases: int


CaseId = Annotated[str, Path(max_length=64, pattern=r"^[A-Za-z0-9_-]+$")]


@router.post(
    "/resolve",
    response_model=ResolveResponse,
    summary="Resolve an observed event to its shared context",
    description=(
        "Scores the observation against recent contexts of the same kind (time, text, subject, modality). "
        "`matched`: joins the best context; `ambiguous`: a near miss, a new context goes to review; "
        "`created`: a new context. Robots resolving the same event at once get one context."
    ),
)
async def resolve(request: ResolveRequest, services: ServicesDep, principal: Publisher) -> ResolveResponse:
    resolution = await run_in_threadpool(services.shared_context.resolve, request.observation(principal.username))
    return ResolveResponse(**asdict(resolution))


@router.post(
    "/reconcile",
    response_model=ReconcileOut,
    summary="Re-examine every ambiguous context",
    description="Merges ambiguous contexts that now have a decisive candidate and refreshes the review cases.",
)
async def reconcile(
    services: ServicesDep, principal: Admin, body: dict[str, object] | None = Body(None)
) -> ReconcileOut:
    report, pending = await run_in_threadpool(services.shared_context.reconcile)
    return ReconcileOut(
        scanned_ambiguous=report.scanned_ambiguous,
        merged_count=len(report.mappings),
        mappings=report.mappings,
        pending_cases=pending,
    )


@router.get("/stats", response_model=StatsOut, summary="Counts of shared contexts and reviews")
async def stats(services: ServicesDep, principal: Auditor) -> StatsOut:
    return StatsOut(**await run_in_threadpool(services.shared_context.stats))


@router.get(
    "/review/pending",
    response_model=ReviewQueueOut,
    summary="The review queue",
    description="Pending review cases with the contexts they compare. Reading it changes nothing.",
)
async def review_pending(services: ServicesDep, principal: Admin) -> ReviewQueueOut:
    queue = await run_in_threadpool(services.shared_context.review_queue)
    return ReviewQueueOut(
        unresolved_count=len(queue.unresolved),
        pending_count=len(queue.pending_cases),
        unresolved_contexts=[ContextOut.of(record) for record in queue.unresolved],
        contexts=[ContextOut.of(record) for record in queue.contexts],
        pending_cases=[CaseOut.of(case) for case in queue.pending_cases],
    )


_REFUSED: dict[int | str, dict[str, Any]] = {
    422: {"description": "No such case, the case is already decided, or the target is not a candidate"}
}


def _decided(decide: Callable[[], Decision]) -> DecisionOut:
    """The reference answers 422 for a case that does not exist or is no longer pending, and its web UI and
    scripts expect that, so those refusals are 422 here too (naming `case_id`)."""
    try:
        return DecisionOut.of(decide())
    except (NotFound, Conflict) as refused:
        raise InvalidParameter("case_id", refused.message) from None


@router.post(
    "/review/{case_id}/accept",
    response_model=DecisionOut,
    summary="Accept a review case: merge its context into the chosen candidate",
    responses=_REFUSED,
)
async def accept(case_id: CaseId, decision: AcceptRequest, services: ServicesDep, principal: Admin) -> DecisionOut:
    return await run_in_threadpool(
        _decided, lambda: services.shared_context.accept(case_id, decision.target_context_uri)
    )


@router.post(
    "/review/{case_id}/reject",
    response_model=DecisionOut,
    summary="Reject a review case: its context stays apart and these candidates are not proposed again",
    responses=_REFUSED,
)
async def reject(
    case_id: CaseId, services: ServicesDep, principal: Admin, body: dict[str, object] | None = Body(None)
) -> DecisionOut:
    return await run_in_threadpool(_decided, lambda: services.shared_context.reject(case_id))
