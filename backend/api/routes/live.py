"""GET /reports/stream: Server-Sent Events telling readers which reports' rows changed, as the rows are kept
current. One stream serves every report (a page showing six reports needs one connection). Resumable: an `id`
per event, and `Last-Event-ID` on reconnection replays what was missed (the last changes are kept; an older id
gets a `reset` event: reload)."""

from __future__ import annotations

import json
from collections.abc import AsyncIterator

import anyio
from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.views.reports import FOLDER

router = APIRouter(tags=["reports"])

POLL_SECONDS = 0.25
KEEP_ALIVE_SECONDS = 15.0


@router.get(
    "/reports/stream",
    summary="Changes of the reports, live (Server-Sent Events)",
    description=(
        'An `event: change` whenever rows of a report changed, with `data: {"report": name, "units": [...]}` '
        "(the keys whose rows were replaced) and an increasing `id`; send it back as `Last-Event-ID` to resume. "
        "`?report=` (repeatable) limits the stream to those reports. `event: reset` when the changes since that id "
        "are no longer kept (reload). A comment every 15 s keeps idle connections open. Reports evaluated in full "
        "on every request (see `served_from`) send no changes."
    ),
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}},
)
async def stream(
    request: Request, services: ServicesDep, principal: Auditor, report: list[str] = Query([])
) -> StreamingResponse:
    wanted = {services.reports.report(name).name for name in report}  # 404 for an unknown report, up front
    maintainer = services.reports.maintainer
    if maintainer is None:
        raise NotFound("This server keeps no live reports.")
    rows = maintainer.rows
    resume = request.headers.get("last-event-id", "")

    async def events() -> AsyncIterator[bytes]:
        last = int(resume) if resume.isdigit() else await anyio.to_thread.run_sync(rows.last_change)
        oldest = await anyio.to_thread.run_sync(rows.oldest_change)
        if resume.isdigit() and last < oldest - 1:
            yield b"event: reset\ndata: {}\n\n"
        yield b"retry: 2000\n\n"
        quiet = 0.0
        while not await request.is_disconnected():
            changes = await anyio.to_thread.run_sync(rows.changes_since, last)
            if changes:
                last = changes[-1][0]
                for name, units in _by_report(changes, wanted).items():
                    data = json.dumps({"report": name.removeprefix(f"{FOLDER}/"), "units": sorted(units)})
                    yield f"id: {last}\nevent: change\ndata: {data}\n\n".encode()
                quiet = 0.0
            elif quiet >= KEEP_ALIVE_SECONDS:
                yield b": keep-alive\n\n"
                quiet = 0.0
            await anyio.sleep(POLL_SECONDS)
            quiet += POLL_SECONDS

    headers = {"Cache-Control": "no-store", "X-Accel-Buffering": "no"}  # proxies must not buffer the stream
    return StreamingResponse(events(), media_type="text/event-stream", headers=headers)


def _by_report(changes: list[tuple[int, str, str]], wanted: set[str]) -> dict[str, set[str]]:
    grouped: dict[str, set[str]] = {}
    for _, name, unit in changes:
        if not wanted or name in wanted:
            grouped.setdefault(name, set()).add(unit)
    return grouped
