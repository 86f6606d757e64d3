"""GET /timeline: one robot's or one human's events over a window, in time order (JSON, CSV, or one HTML file),
and GET /timeline/stream: the window's events as they change, live."""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Annotated

import anyio
from fastapi import APIRouter, Depends, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response, StreamingResponse

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.responses import FastJSONResponse
from segb_server.backend.api.routes.live import ENDS_WITH_THE_TOKEN, ChangeFeed, event_id, event_stream
from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.formats import Format, negotiate
from segb_server.backend.services.timeline.kinds import FOLDER
from segb_server.backend.services.timeline.service import (
    DEFAULT_LIMIT,
    MAX_DOCUMENT_ROWS,
    MAX_LIMIT,
    TimelineService,
)
from segb_server.backend.services.timeline.sources import Window
from segb_server.backend.services.timeline.standalone import standalone_html, viewer_file

router = APIRouter(tags=["timeline"])

FORMATS = (
    Format("json", "application/json", extension="json"),
    Format("csv", "text/csv", extension="csv"),
    Format("html", "text/html", extension="html"),
)
VIEWER = {"js": "text/javascript", "css": "text/css"}  # the viewer's files, which the web UI's page loads


@dataclass(frozen=True)
class Asked:
    """What a timeline request asks for: its window (checked) and its kinds."""

    window: Window
    kinds: list[str]


async def asked(
    services: ServicesDep,
    robot: Annotated[str | None, Query(description="The robot whose timeline this is (an IRI)")] = None,
    human: Annotated[str | None, Query(description="The human whose timeline this is (an IRI); robot or human")] = None,
    since: Annotated[str | None, Query(description="Only events at or after this time (ISO 8601, a zone)")] = None,
    until: Annotated[str | None, Query(description="Only events at or before this time (ISO 8601, a zone)")] = None,
    kind: Annotated[list[str], Query(description="Only these kinds (repeatable, or comma-separated)")] = [],  # noqa: B006
) -> Asked:
    """The filters `GET /timeline` and its stream share; a 422 naming a bad one."""
    window = services.timeline.window({"robot": robot, "human": human, "since": since, "until": until})
    return Asked(window, services.timeline.chosen_kinds(kind))


AskedDep = Annotated[Asked, Depends(asked)]


@router.get(
    "/timeline",
    summary="One robot's or one human's events over a window, in time order",
    description=(
        "Every logged event of the robot (or human) in the window, across kinds — shared events, perceptions, "
        "listening, decisions, responses, other activities, model invocations, observations, messages heard and "
        "said, emotions read and expressed, robot states, and the audit rules' findings (those with a time) — "
        "one row each: `time`, `kind`, an honest one-line "
        "`sentence`, `robot`, `humans`, the `iri` it is about and links to its explanation (`explain`) and to the "
        "graph around it (`graph`). JSON `{robot, human, since, until, kinds, columns, rows, limit, has_more, "
        "next, served_from, last_event_id}`, or CSV with `Accept: text/csv` or `?format=csv`. Page with `after=` "
        "the previous page's `next`. `last_event_id`: send it as `Last-Event-ID` to `GET /timeline/stream`. "
        f"`?format=html` (or `Accept: text/html`): the window's first {MAX_DOCUMENT_ROWS:,} events as one "
        "self-contained HTML file that opens with no server."
    ),
    responses={200: {"content": {"application/json": {}, "text/csv": {}, "text/html": {}}}, 422: {}},
)
async def timeline(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    ask: AskedDep,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT, description=f"Events per page (1 to {MAX_LIMIT})")] = DEFAULT_LIMIT,
    after: Annotated[str | None, Query(description="The `next` of the previous page")] = None,
    format: Annotated[str | None, Query(description="json, csv or html; overrides Accept")] = None,
) -> Response:
    fmt = negotiate(FORMATS, request.headers.get("accept"), format, what="a timeline")
    window, kinds = ask.window, ask.kinds

    def work() -> Response:
        if fmt.name == "html":
            return _document(services.timeline, window, kinds, request)
        page = services.timeline.page(window, kinds, limit, after)
        if fmt.name == "csv":
            headers = {"Content-Disposition": 'attachment; filename="timeline.csv"'}
            return Response(page.as_csv(), media_type=fmt.content_type, headers=headers)
        return FastJSONResponse(page.as_json())

    return await run_in_threadpool(work)


@router.get(
    "/timeline/stream",
    summary="One robot's or one human's timeline, live (Server-Sent Events)",
    description=(
        'An `event: rows` with `data: {"kind", "keys", "rows"}` whenever events of that kind changed: `keys` are '
        "the IRIs whose events were replaced, `rows` their events in the window now (as `GET /timeline` gives them; "
        "none when they left it). The last event of each group of changes carries an increasing `id`: send it "
        "back as `Last-Event-ID` to resume; `event: reset` when the changes since that id are no longer kept "
        "(reload). Same filters as `GET /timeline`. A comment every 15 s keeps idle connections open."
        + ENDS_WITH_THE_TOKEN
    ),
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}},
)
async def timeline_stream(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    ask: AskedDep,
) -> StreamingResponse:
    window, kinds = ask.window, set(ask.kinds)
    kept = services.timeline_rows
    feed = ChangeFeed(kept.rows, event_id(request.headers.get("last-event-id", "")))
    await feed.start()  # before the answer's headers go out: a change made once the reader sees them is sent

    async def changes() -> list[bytes]:
        keys: dict[str, dict[str, None]] = {}
        for _, view, unit in await feed.changes():
            kind = view.removeprefix(f"{FOLDER}/")
            if kind in kinds and unit.startswith("<") and unit.endswith(">"):
                keys.setdefault(kind, {})[unit[1:-1]] = None
        events = []
        for index, (kind, changed) in enumerate(keys.items()):
            rows = await anyio.to_thread.run_sync(services.timeline.changed, kind, window, list(changed))
            data = json.dumps({"kind": kind, "keys": list(changed), "rows": rows})
            events.append(feed.event("rows", data, last=index == len(keys) - 1))
        return events

    return event_stream(request, feed.opening, changes, kept.rows.changed, principal.expires_at)


def _document(timeline: TimelineService, window: Window, kinds: list[str], request: Request) -> Response:
    rows, truncated = timeline.whole(window, kinds)
    subject = f"Robot <{window.robot}>" if window.robot else f"Human <{window.human}>"
    if window.robot and window.human:
        subject += f" with human <{window.human}>"
    html = standalone_html(
        rows,
        title="Timeline",
        subject=subject,
        since=window.since,
        until=window.until,
        kinds=timeline.kinds,
        truncated=truncated,
        generated_at=datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        generator=f"the SEGB server at {request.base_url}",
    )
    headers = {"Content-Disposition": 'attachment; filename="timeline.html"'}
    return Response(html, media_type="text/html; charset=utf-8", headers=headers)


@router.get("/timeline/viewer.{extension}", include_in_schema=False)
async def viewer(extension: str) -> Response:
    """The timeline viewer's script and style (public: no data in them), which the web UI's page loads."""
    if extension not in VIEWER:
        raise NotFound("The timeline viewer's files are /timeline/viewer.js and /timeline/viewer.css.")
    headers = {"Cache-Control": "public, max-age=300"}
    return Response(viewer_file(f"timeline.{extension}"), media_type=VIEWER[extension], headers=headers)
