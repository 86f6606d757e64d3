"""GET /ledger and GET /ledger/verify: the receipts of accepted posts, and a check of their hash chain."""

from __future__ import annotations

from dataclasses import asdict
from typing import Annotated, Literal

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.paging import Offset

router = APIRouter(tags=["ledger"])

MAX_LIMIT = 1000


class ReceiptOut(BaseModel):
    sequence: int = Field(description="Position in the chain, from 1, without gaps.")
    log_id: str = Field(description="The `log_id` the post's response carried.")
    action: str = Field(description="`ingest` or `delete_all`.")
    user: str = Field(description="Authenticated identity of the poster.")
    claimed_user: str | None = Field(description="The user the client claimed in its body or `?user=`.")
    recorded_at: str = Field(description="UTC time of the receipt, ISO 8601 with `Z`.")
    payload_sha256: str = Field(
        description="SHA-256 (hex) of the RDF as received, after gzip decoding; of the empty payload for delete_all."
    )
    triples_received: int
    triples_new: int
    triples_removed: int = Field(description="Triples a delete_all removed; 0 for an ingest.")
    previous_hash: str = Field(description="`receipt_hash` of the receipt before; 64 zeros for the first.")
    receipt_hash: str = Field(description="SHA-256 of the canonical JSON of every other field of this receipt.")


class LedgerPage(BaseModel):
    receipts: list[ReceiptOut] = Field(description="Newest first.")
    total: int
    limit: int
    offset: int


class BrokenLinkOut(BaseModel):
    sequence: int
    log_id: str
    reason: Literal["hash mismatch", "previous hash does not match", "sequence gap"]


class VerificationOut(BaseModel):
    valid: bool
    receipts: int = Field(description="Receipts in the ledger.")
    first_broken: BrokenLinkOut | None = Field(None, description="Only when the chain is broken.")


@router.get(
    "/ledger",
    response_model=LedgerPage,
    summary="List the ingest receipts",
    description=(
        "One receipt per accepted `POST /ttl` and `POST /ttl/delete_all`, newest first, hash-chained: "
        "see `GET /ledger/verify`. Paging: `limit` (1 to 1000, default 100) and `offset`."
    ),
)
async def list_receipts(
    services: ServicesDep,
    principal: Auditor,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT)] = 100,
    offset: Offset = 0,
) -> LedgerPage:
    receipts, total = await run_in_threadpool(services.ledger.page, limit, offset)
    return LedgerPage(
        receipts=[ReceiptOut(**asdict(receipt)) for receipt in receipts], total=total, limit=limit, offset=offset
    )


@router.get(
    "/ledger/verify",
    response_model=VerificationOut,
    response_model_exclude_none=True,
    summary="Check the ledger's hash chain",
    description=(
        "Recomputes every receipt's hash and link, oldest first. A broken chain names its first broken "
        "receipt and why: `hash mismatch` (the receipt was edited), `previous hash does not match` or "
        "`sequence gap` (a receipt before it was removed or rewritten)."
    ),
)
async def verify_ledger(services: ServicesDep, principal: Auditor) -> VerificationOut:
    checked = await run_in_threadpool(services.ledger.verify)
    broken = checked.first_broken
    return VerificationOut(
        valid=checked.valid,
        receipts=checked.receipts,
        first_broken=BrokenLinkOut(**asdict(broken)) if broken else None,
    )
