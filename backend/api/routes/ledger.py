"""GET /ledger, GET /ledger/{log_id} and GET /ledger/verify: the journal's receipts, one with its content as
received, and a check of the hash chain."""

from __future__ import annotations

import json
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.paging import Offset
from segb_server.backend.api.responses import FastJSONResponse
from segb_server.backend.services.formats import Format as MediaFormat
from segb_server.backend.services.formats import negotiate
from segb_server.backend.services.writing.receipts import BrokenReason

router = APIRouter(tags=["ledger"])

MAX_LIMIT = 1000
RECEIPT_FIELDS = (
    "`sequence` (position in the chain, from 1, without gaps), `log_id` (as in the post's answer), `action` "
    "(`ingest` or `delete_all`), `user` (authenticated identity), `claimed_user`, `recorded_at` (UTC), "
    "`payload_sha256` (SHA-256 of the RDF as received, after gzip decoding; of the empty payload for a "
    "clearing), `triples_received`, `triples_new`, `triples_removed`, `content_sha256` (SHA-256 of the new "
    "triples as the journal keeps them: an N-Triples document; absent on receipts from before the journal kept "
    "content), `previous_hash` and `receipt_hash` (SHA-256 of the canonical JSON of every other field)"
)
_CONTENT_FORMATS = (
    MediaFormat("json", "application/json"),
    MediaFormat("ntriples", "application/n-triples"),
)


class LedgerPage(BaseModel):
    receipts: list[dict[str, Any]] = Field(description=f"Newest first. Each receipt: {RECEIPT_FIELDS}.")
    total: int
    limit: int
    offset: int


class BrokenLinkOut(BaseModel):
    sequence: int
    log_id: str
    reason: BrokenReason


class VerificationOut(BaseModel):
    valid: bool
    receipts: int = Field(description="Receipts in the ledger.")
    deep: bool | None = Field(None, description="True when every entry's content was hashed again too.")
    redactions: int | None = Field(
        None,
        description="Erasures in the chain (only when there are any): each removed triples from earlier posts and "
        "is recorded as an entry (who, when, why, which posts); a deep check verifies what remains of those posts "
        "against it.",
    )
    first_broken: BrokenLinkOut | None = Field(None, description="Only when the chain is broken.")


@router.get(
    "/ledger",
    response_model=LedgerPage,
    summary="List the ingest receipts",
    description=(
        "One receipt per accepted `POST /ttl`, `POST /ttl/delete_all` and import batch, newest first, "
        "hash-chained: see `GET /ledger/verify`. Paging: `limit` (1 to 1000, default 100) and `offset`."
    ),
)
async def list_receipts(
    services: ServicesDep,
    principal: Auditor,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT)] = 100,
    offset: Offset = 0,
) -> LedgerPage:
    receipts, total = await run_in_threadpool(services.writes.journal.page, limit, offset)
    return LedgerPage(receipts=[receipt.public() for receipt in receipts], total=total, limit=limit, offset=offset)


@router.get(
    "/ledger/verify",
    response_model=VerificationOut,
    response_model_exclude_none=True,
    summary="Check the ledger's hash chain",
    description=(
        "Recomputes every receipt's hash and link, oldest first; with `deep=true` also the SHA-256 of every "
        "entry's content. A broken chain names its first broken receipt and why: `hash mismatch` (the receipt "
        "was edited), `previous hash does not match` or `sequence gap` (a receipt before it was removed or "
        "rewritten), `content does not match` (the kept triples were edited)."
    ),
)
async def verify_ledger(
    services: ServicesDep,
    principal: Auditor,
    deep: Annotated[bool, Query(description="Hash every entry's content too.")] = False,
) -> VerificationOut:
    checked = await run_in_threadpool(lambda: services.writes.journal.verify(deep=deep))
    broken = checked.first_broken
    return VerificationOut(
        valid=checked.valid,
        receipts=checked.receipts,
        deep=checked.deep or None,
        redactions=checked.redactions or None,
        first_broken=BrokenLinkOut(sequence=broken.sequence, log_id=broken.log_id, reason=broken.reason)
        if broken
        else None,
    )


@router.get(
    "/ledger/{log_id}",
    summary="One receipt with the triples it recorded",
    description=(
        "The receipt and its content: the post's new triples exactly as received (original lexical forms, "
        "datatypes and language tags; blank nodes skolemised), as an N-Triples document. JSON "
        "`{receipt, content}` by default; `Accept: application/n-triples` (or `?format=ntriples`) gives the "
        "document alone, whose SHA-256 is the receipt's `content_sha256` (unless an erasure removed triples from it "
        "since: the receipt's `content_digest` and the erasure's record then verify it). An erasure's entry "
        "answers `{receipt, content: null, redaction}`: its record (kind, reason, and for each post it redacted "
        "its `sequence`, `log_id`, `triples_removed` and the `remaining_sha256` of what is left). 404 for an "
        "unknown `log_id`."
    ),
    responses={200: {"content": {"application/json": {}, "application/n-triples": {}}}, 404: {}},
)
async def receipt(
    log_id: str, request: Request, services: ServicesDep, principal: Auditor, format: str | None = Query(None)
) -> Response:
    fmt = negotiate(_CONTENT_FORMATS, request.headers.get("accept"), format, what="a receipt")
    found, content = await run_in_threadpool(services.writes.journal.entry, log_id)
    if found.action == "erase":  # its content is the erasure's record, not triples
        record = json.loads(content or b"{}")
        if fmt.name == "ntriples":
            return Response(b"", media_type=fmt.media_type)
        return FastJSONResponse({"receipt": found.public(), "content": None, "redaction": record})
    if fmt.name == "ntriples":
        return Response(content or b"", media_type=fmt.media_type)
    body = {"receipt": found.public(), "content": None if content is None else content.decode("utf-8")}
    return FastJSONResponse(body)
