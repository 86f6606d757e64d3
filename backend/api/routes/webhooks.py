"""The webhooks' latest deliveries (admin), and sending one again."""

from __future__ import annotations

import json

from fastapi import APIRouter, Request
from pydantic import BaseModel, Field

from segb_server.backend.api.deps import Admin
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.observability.deliveries import Deliveries, Delivery

router = APIRouter(tags=["webhooks"])


class DeliveryPublic(BaseModel):
    id: str
    event: str = Field(examples=["finding.new"])
    body: dict[str, object] = Field(description="The JSON that was posted.")
    outcomes: dict[str, str] = Field(description="Each URL → `delivered`, or the last failure once retries ran out.")


def _deliveries(request: Request) -> Deliveries:
    webhooks = request.app.state.watching.webhooks
    if webhooks is None:
        raise NotFound("No webhooks are configured (WEBHOOK_URLS).")
    return webhooks.deliveries


def _public(delivery: Delivery) -> DeliveryPublic:
    return DeliveryPublic(
        id=delivery.id, event=delivery.event, body=json.loads(delivery.body), outcomes=dict(delivery.outcomes)
    )


@router.get(
    "/webhooks/deliveries",
    summary="The latest webhook deliveries",
    description="Newest first, the last 500 since the server started or the last erasure. 404 without WEBHOOK_URLS.",
)
async def deliveries(request: Request, principal: Admin) -> list[DeliveryPublic]:
    return [_public(delivery) for delivery in _deliveries(request).remembered()]


@router.post(
    "/webhooks/deliveries/{delivery_id}/redeliver",
    status_code=202,
    summary="Send a webhook delivery again",
    description="Queues the same body with the same `X-SEGB-Delivery` id, signed anew. 404 when not remembered.",
)
async def redeliver(request: Request, principal: Admin, delivery_id: str) -> DeliveryPublic:
    return _public(_deliveries(request).redeliver(delivery_id))
