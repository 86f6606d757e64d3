"""GET /evidence (auditor): a signed bundle of one window of what robots logged, which anyone can check offline
(`segb verify-evidence`); GET /.well-known/segb-evidence-key (public): the key it is checked with."""

from __future__ import annotations

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from segb_server.backend.api.deps import Auditor, ServicesDep

router = APIRouter(tags=["evidence"])
KEY_PATH = "/.well-known/segb-evidence-key"


@router.get(
    "/evidence",
    summary="A signed evidence bundle of one window",
    description=(
        "A zip archive an investigator can take away: the window's triples exactly as the robots sent them (from "
        "the journal), the receipts carrying them with the hash chain from the first of them to the head, a "
        "manifest (who exported, when, which server, which query) and the window's timeline as one "
        "self-contained HTML page, signed with the server's Ed25519 key (public at "
        f"`{KEY_PATH}`). `segb verify-evidence BUNDLE --public-key KEY` checks it offline and names every "
        "failure. The window: activities performed by `robot` (every robot when absent) with a time between "
        "`since` and `until`, what they produced, and the robot's states of that time. 422 for a bad value."
    ),
    responses={200: {"content": {"application/zip": {}}}, 422: {}},
)
async def evidence(
    services: ServicesDep,
    principal: Auditor,
    robot: str | None = Query(None, description="The robot's IRI."),
    since: str | None = Query(None, description="ISO 8601 with a time zone, e.g. 2026-03-10T09:00:00Z."),
    until: str | None = Query(None, description="ISO 8601 with a time zone."),
) -> Response:
    filters = {"robot": robot, "since": since, "until": until}
    bundle = await run_in_threadpool(services.evidence.build, filters, principal.username)
    name = f"evidence-{bundle.head}.zip"
    return Response(
        bundle.data, media_type="application/zip", headers={"Content-Disposition": f'attachment; filename="{name}"'}
    )


@router.get(
    KEY_PATH,
    summary="The server's public key for evidence bundles",
    description="PEM (Ed25519, SubjectPublicKeyInfo); its SHA-256 fingerprint is in the `X-Key-Fingerprint` header.",
    responses={200: {"content": {"application/x-pem-file": {}}}},
)
async def evidence_key(services: ServicesDep) -> Response:
    key = services.evidence.key
    return Response(
        key.public_pem(), media_type="application/x-pem-file", headers={"X-Key-Fingerprint": key.fingerprint}
    )
