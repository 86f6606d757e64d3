"""Publishing robots' logs: POST /ttl (as the PyPI client sends them) and clearing the events graph."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Admin, LimitedBody, Publisher, ServicesDep
from segb_server.backend.services.ingest.payloads import DeleteAllRequest, IngestRequest, decode_ingest_body
from segb_server.backend.services.ingest.service import IngestResult

router = APIRouter(tags=["ingest"])


class IngestResponse(BaseModel):
    message: str = Field(examples=["Stored 57 triples (57 new)."])
    log_id: str = Field(description="Identifier of this post (also in the server log and the ledger).")
    triples_received: int = Field(description="Triples in the payload.")
    triples_new: int = Field(description="Triples the store did not have yet; 0 for a pure re-publish.")
    triples_withheld: int = Field(
        0,
        description="Triples an erasure removed that the post sent again: not recorded, so an erased person does not "
        "come back with a robot's cumulative re-publish (see docs/personal-data.md).",
    )
    user: str = Field(description="Authenticated identity the post is recorded under.")
    claimed_user: str | None = Field(description="The body's `user` field, as claimed by the client.")


class DeleteAllResponse(BaseModel):
    message: str = Field(examples=["Graph cleared."])
    log_id: str = Field(description="Identifier of this clearing (also in the ledger).")
    triples_removed: int


_RDF_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": IngestRequest.model_json_schema()},
            "text/turtle": {"schema": {"type": "string"}, "example": "<https://ex.org/a> a <https://ex.org/B> ."},
            "application/n-triples": {"schema": {"type": "string"}},
        },
    }
}


@router.post(
    "/ttl",
    status_code=201,
    response_model=IngestResponse,
    summary="Publish RDF (Turtle or N-Triples)",
    description=(
        "Stores a robot's log. The body is the JSON `SEGBPublisher` sends (`ttl_content`, `user`), or raw "
        "`text/turtle` / `application/n-triples` (claimed user in `?user=`); `Content-Encoding: gzip` is "
        "accepted. The post is recorded in the journal with its receipt first; a 201 means it is durable there "
        "and, with `INGEST_ACK=store` (the embedded store's default), applied to the store too. While the "
        "reports are more than `VIEWS_MAX_LAG_SECONDS` behind, the answer waits for them (up to "
        "`VIEWS_MAX_HOLD_SECONDS`), so robots post at the pace the reports keep. Re-publishing is "
        "idempotent: only triples the journal lacks are recorded and written, and blank nodes are skolemised "
        "deterministically. A token with write scopes may only describe subjects under them (403 naming the "
        "first other one). Errors: 400 malformed RDF (with line and column) or RDF 1.2 triple terms, 403 out "
        "of scope, 413 too large, 415 unsupported Content-Type, 422 empty or malformed body, 503 with "
        "`Retry-After` when the store lags too far behind or (with `INGEST_ACK=store`) does not answer, 507 "
        "when the journal's disk is full. Nothing is written on any error but the 503 after journaling, whose "
        "post is kept and applied once the store answers."
    ),
    openapi_extra=_RDF_BODY,
    responses={
        400: {"description": "Malformed RDF"},
        403: {"description": "Out of the token's scopes"},
        413: {"description": "Too large"},
        415: {},
        422: {},
        503: {"description": "Store behind or unavailable"},
        507: {"description": "Journal disk full"},
    },
)
async def publish(
    request: Request, body: LimitedBody, services: ServicesDep, principal: Publisher, user: str | None = None
) -> IngestResponse:
    def work() -> tuple[IngestResult, str | None]:
        payload = decode_ingest_body(
            body,
            content_type=request.headers.get("content-type"),
            content_encoding=request.headers.get("content-encoding"),
            claimed_user=user,
            max_decompressed_bytes=services.settings.max_decompressed_bytes,
        )
        result = services.ingest.ingest(payload, actor=principal.username, scopes=principal.scopes)
        return result, payload.claimed_user

    result, claimed = await run_in_threadpool(work)
    await services.views_pace.hold()  # kept already; robots wait for this answer before their next post
    # For the request's log line, which is the one line an ingest writes at INFO.
    request.state.triples_written, request.state.log_id = result.triples_new, result.log_id
    return IngestResponse(
        message=f"Stored {result.triples_received} {_triples(result.triples_received)} ({result.triples_new} new).",
        log_id=result.log_id,
        triples_received=result.triples_received,
        triples_new=result.triples_new,
        triples_withheld=result.triples_withheld,
        user=principal.username,
        claimed_user=claimed,
    )


@router.post(
    "/ttl/delete_all",
    response_model=DeleteAllResponse,
    summary="Clear the events graph",
    description='Removes every triple of the events graph (admin). The body `{"user": …}` is optional.',
)
def delete_all(services: ServicesDep, principal: Admin, body: DeleteAllRequest | None = None) -> DeleteAllResponse:
    # A plain `def` route runs in the thread pool, so the journal's write stays off the event loop.
    cleared = services.ingest.delete_all(actor=principal.username, claimed_user=body.user if body else None)
    return DeleteAllResponse(
        message="Graph cleared." if cleared.triples_removed else "No TTLs to delete",
        log_id=cleared.log_id,
        triples_removed=cleared.triples_removed,
    )


def _triples(count: int) -> str:
    return "triple" if count == 1 else "triples"
