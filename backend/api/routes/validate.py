"""POST /ttl/validate: would POST /ttl take this document, and does it follow the reference's rules? (admin)"""

from __future__ import annotations

from dataclasses import asdict
from typing import Literal

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Admin, LimitedBody, ServicesDep
from segb_server.backend.services.ingest.payloads import IngestRequest
from segb_server.backend.services.ingest.validation import MAX_ISSUES, ValidationReport, validate_body
from segb_server.backend.services.rules.offline import check_quads

router = APIRouter(tags=["ingest"])

# The body is read raw (as POST /ttl reads it), so its shapes are documented here rather than by a model.
_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": IngestRequest.model_json_schema()},
            "text/turtle": {"schema": {"type": "string"}},
            "application/n-triples": {"schema": {"type": "string"}},
        },
    }
}


class IssueOut(BaseModel):
    severity: Literal["error", "warning"]
    code: str = Field(examples=["TTL_SYNTAX_ERROR", "SEM_INTENSITY_OUT_OF_RANGE"])
    message: str
    focus_node: str | None = Field(description="The subject the finding is about, when there is one.")
    predicate: str | None
    value: str | None = Field(description="The object: an IRI or a literal's lexical form.")
    line: int | None = Field(description="Line of a syntax error (1-based), when known.")
    column: int | None = Field(description="Column of a syntax error (1-based), when known.")


class FindingOut(BaseModel):
    rule: str = Field(examples=["late-answer"])
    severity: Literal["violation", "warning", "info"]
    title: str
    focus: str | None = Field(description="What the finding is about (an IRI).")
    message: str | None
    time: str | None
    robot: str | None
    human: str | None
    values: dict[str, object]
    line: int | None = Field(description="The first line of the document that names the focus, when one does.")


class ValidationOut(BaseModel):
    valid: bool = Field(description="No finding of severity `error` (as the reference reports it).")
    syntax_ok: bool = Field(description="The parser found no syntax error.")
    semantic_ok: bool = Field(description="Equal to `valid`, as in the reference.")
    triple_count: int = Field(description="Triples POST /ttl would receive; 0 when it would refuse the document.")
    issues: list[IssueOut] = Field(description=f"Errors in document order, then warnings; at most {MAX_ISSUES}.")
    ingest_ok: bool = Field(
        description="POST /ttl would store this document for this caller (the reference's rules aside)."
    )
    error_count: int
    warning_count: int
    issues_truncated: bool = Field(description=f"More than {MAX_ISSUES} findings: `issues` holds the first ones.")
    findings: list[FindingOut] = Field(
        description="What the audit rules (GET /rules) find in this document by itself, in time order."
    )
    rules_ok: bool = Field(description="No audit rule of severity `violation` finds anything in the document.")

    @classmethod
    def of(cls, report: ValidationReport) -> ValidationOut:
        violations = sum(1 for found in report.findings if found["severity"] == "violation")
        return cls(
            **asdict(report),
            valid=report.valid,
            semantic_ok=report.valid,
            issues_truncated=report.issues_truncated,
            rules_ok=violations == 0,
        )


@router.post(
    "/ttl/validate",
    response_model=ValidationOut,
    summary="Check a document without storing it",
    description=(
        'Compatible with the reference backend: the body POST /ttl takes (`{"ttl_content": …}` as the PyPI client '
        "and the reference UI send it, or raw Turtle / N-Triples, gzip allowed); the answer is 200 with `valid`, "
        "`syntax_ok`, `semantic_ok`, `triple_count` and `issues` (`severity`, `code`, `message`, `focus_node`, "
        "`predicate`, `value`, and `line`/`column` for a syntax error). Findings: what POST /ttl refuses "
        "(`TTL_SYNTAX_ERROR` — relative IRIs among them —, `INGEST_REFUSED` for RDF 1.2 triple terms, "
        "`INGEST_TOO_LARGE` over MAX_TRIPLES_PER_POST, `INGEST_OUT_OF_SCOPE` for a subject outside the token's "
        "write scopes, `SEM_EMPTY_GRAPH`) and the reference's rules on the robots' "
        "vocabulary (`SEM_RDF_TYPE_LITERAL`, `SEM_OBJECT_PROPERTY_LITERAL`, `SEM_DATETIME_*`, `SEM_INTENSITY_*`, "
        "`SEM_EMOTION_CATEGORY_LITERAL`, and the warning `SEM_SUBJECT_WITHOUT_TYPE`). `ingest_ok` tells whether "
        "POST /ttl would store the document. `findings`: what the audit rules (`GET /rules`) find in the document "
        "by itself (evaluated on an in-memory store holding only it: a robot's client posts its whole log), each "
        "with the `line` that first names its focus; `rules_ok` is false when one of them is a violation (`valid` "
        "keeps the reference's meaning). Nothing is written and the store is not needed. A request POST /ttl "
        "would refuse before reading RDF gets its status: 413 over MAX_BODY_BYTES or MAX_DECOMPRESSED_BYTES, 415 "
        "for another Content-Type or Content-Encoding, 422 for a malformed JSON body."
    ),
    openapi_extra=_BODY,
    responses={413: {"description": "Too large"}, 415: {}, 422: {}},
)
async def validate(request: Request, services: ServicesDep, principal: Admin, body: LimitedBody) -> ValidationOut:
    settings = services.settings
    report = await run_in_threadpool(
        validate_body,
        body,
        content_type=request.headers.get("content-type"),
        content_encoding=request.headers.get("content-encoding"),
        max_decompressed_bytes=settings.max_decompressed_bytes,
        max_triples=settings.max_triples_per_post,
        scopes=principal.scopes,
        rules=lambda quads, data: (
            check_quads(
                services.findings.catalog, quads, data.decode("utf-8", errors="replace"), services.findings.shape_rules
            ).findings
        ),
    )
    return ValidationOut.of(report)
