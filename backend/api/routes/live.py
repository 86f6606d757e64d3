"""Server-Sent Events telling readers that a view changed, as the views are kept current from the journal.

`GET /reports/stream` says which reports' rows changed; one stream serves every report (a page showing six
reports needs one connection). Resumable: an `id` on the last event of each group of changes, and
`Last-Event-ID` on reconnection replays what was missed (the last changes are kept; an older id, or one the
stream has not reached, gets a `reset` event: reload). `GET /graph/stream` says that the drawable graph
changed; a viewer fetches its view again, so a reconnection needs no replay."""

from __future__ import annotations

import json
import time
from collections.abc import AsyncIterator, Awaitable, Callable

import anyio
from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.services.reports.folder import FOLDER
from segb_server.backend.services.views.kept_queries.rows import KeptRows
from segb_server.backend.services.views.signal import ChangeSignal

router = APIRouter(tags=["reports"])

POLL_SECONDS = 0.1  # how soon a reader hears of another process's change: a cheap read per open stream
KEEP_ALIVE_SECONDS = 15.0
# The last event of a stream whose token expired: a reader holding that token may read no more (a new request
# with it is refused), so the stream ends rather than outliving the token.
EXPIRED = (
    b'event: expired\ndata: {"detail": "The token this stream was opened with expired: open it again with a new one."}'
    b"\n\n"
)
MAX_EVENT_ID_DIGITS = 18
ENDS_WITH_THE_TOKEN = " It ends with `event: expired` when the token it was opened with expires."  # every stream's


@router.get(
    "/reports/stream",
    summary="Changes of the reports, live (Server-Sent Events)",
    description=(
        'An `event: change` whenever rows of a report changed, with `data: {"report": name, "units": [...]}` '
        "(the keys whose rows were replaced); the last event of each group of changes carries an increasing `id`: "
        "send it back as `Last-Event-ID` to resume. "
        "`?report=` (repeatable) limits the stream to those reports. `event: reset` when the changes since that id "
        "are no longer kept, or the id is ahead of the stream (reload). A comment every 15 s keeps idle connections "
        "open. Reports evaluated in full on every request (see `served_from`) send no changes." + ENDS_WITH_THE_TOKEN
    ),
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}},
)
async def stream(
    request: Request, services: ServicesDep, principal: Auditor, report: list[str] = Query([])
) -> StreamingResponse:
    wanted = {services.reports.report(name).name for name in report}  # 404 for an unknown report, up front
    change_log = services.reports.change_log()  # 404 when no report is kept as rows
    served = services.reports.served_by_rows()
    feed = ChangeFeed(change_log, event_id(request.headers.get("last-event-id", "")))
    # Where a new reader starts is read before the answer's headers go out: a change made as soon as the
    # reader sees them is after it, and is sent.
    await feed.start()

    async def changes() -> list[bytes]:
        found = await feed.changes()
        grouped = list(_by_report(found, wanted, served).items())
        events = []
        for index, (name, units) in enumerate(grouped):
            data = json.dumps({"report": name.removeprefix(f"{FOLDER}/"), "units": sorted(units)})
            events.append(feed.event("change", data, last=index == len(grouped) - 1))
        return events

    return event_stream(request, feed.opening, changes, change_log.changed, principal.expires_at)


@router.get(
    "/graph/stream",
    tags=["graph"],
    summary="Changes of the drawable graph, live (Server-Sent Events)",
    description=(
        'An `event: change` with `data: {"through": n}` whenever what `GET /graph` draws changed (new nodes, '
        "links, labels or times, or a clearing); `n`, also the event's `id`, is the journal entry the graph now "
        "includes. Fetch the view again on each. With `Last-Event-ID` older than the graph, one change is sent at "
        "once. A comment every 15 s keeps idle connections open." + ENDS_WITH_THE_TOKEN
    ),
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}},
)
async def graph_stream(request: Request, services: ServicesDep, principal: Auditor) -> StreamingResponse:
    index = services.graph.index
    resume = request.headers.get("last-event-id", "")
    seen = -1 if resume and resume != str(index.changed_through) else index.changed_through

    async def changes() -> list[bytes]:
        nonlocal seen
        current = index.changed_through
        if current == seen:
            return []
        seen = current
        return [f"id: {current}\nevent: change\ndata: {json.dumps({'through': current})}\n\n".encode()]

    async def opening() -> list[bytes]:
        return []

    return event_stream(request, opening, changes, index.changed, principal.expires_at)


def event_id(raw: str) -> int | None:
    """A report stream's position as a reader sends it back, or None for anything the stream never sent: the
    reader then starts from now. Ids fit SQLite's integers (under 19 digits); larger ones are no position."""
    return int(raw) if raw.isascii() and raw.isdigit() and len(raw) <= MAX_EVENT_ID_DIGITS else None


def event_stream(
    request: Request,
    opening: Callable[[], Awaitable[list[bytes]]],
    changes: Callable[[], Awaitable[list[bytes]]],
    changed: ChangeSignal,
    expires_at: int | None,
) -> StreamingResponse:
    """An event stream: `opening`'s events, then `changes`' events, looked for whenever `changed` wakes the
    reader (or every `POLL_SECONDS`) until the reader leaves, with a keep-alive comment when quiet; it ends with
    `EXPIRED` once `expires_at` (Unix seconds: the expiry of the token that opened it) has passed."""

    def expired() -> bool:
        return expires_at is not None and time.time() >= expires_at

    async def events() -> AsyncIterator[bytes]:
        for event in await opening():
            yield event
        yield b"retry: 2000\n\n"
        quiet_since = time.monotonic()
        while not await request.is_disconnected():
            if expired():
                yield EXPIRED
                return
            found = await changes()
            for event in found:
                yield event
            now = time.monotonic()
            if found:
                quiet_since = now
            elif now - quiet_since >= KEEP_ALIVE_SECONDS:
                yield b": keep-alive\n\n"
                quiet_since = now
            await changed.wait(POLL_SECONDS if expires_at is None else min(POLL_SECONDS, expires_at - time.time()))

    headers = {"Cache-Control": "no-store", "X-Accel-Buffering": "no"}  # proxies must not buffer the stream
    return StreamingResponse(events(), media_type="text/event-stream", headers=headers)


class ChangeFeed:
    """A reader's place in the changes of kept rows (`KeptRows.changes_since`): where it starts (the position it
    resumes from, or now), whether it missed what is no longer kept, and what is new since."""

    def __init__(self, rows: KeptRows, resume: int | None) -> None:
        self.rows = rows
        self.resume = resume
        self.last = resume if resume is not None else 0

    async def start(self) -> None:
        if self.resume is None:
            self.last = await anyio.to_thread.run_sync(self.rows.last_change)

    async def opening(self) -> list[bytes]:
        if self.resume is None:
            return []
        oldest, newest = await anyio.to_thread.run_sync(lambda: (self.rows.oldest_change(), self.rows.last_change()))
        if oldest - 1 <= self.last <= newest:
            return []
        # Changes no longer kept, or a position these rows never reached (built again since the reader's page
        # was read): what was missed is unknown, so the reader reloads, and hears what follows from now on.
        self.last = min(self.last, newest)
        return [b"event: reset\ndata: {}\n\n"]

    async def changes(self) -> list[tuple[int, str, str]]:
        """(position, view, unit) of the changes since the last look."""
        found = await anyio.to_thread.run_sync(self.rows.changes_since, self.last)
        if found:
            self.last = found[-1][0]
        return found

    def event(self, name: str, data: str, *, last: bool) -> bytes:
        """One event of a group of changes. The id goes on the group's last event only: a reader that leaves in
        the middle resumes from the previous id and hears the whole group again, rather than skipping what it
        had not heard yet."""
        position = f"id: {self.last}\n" if last else ""
        return f"{position}event: {name}\ndata: {data}\n\n".encode()


def _by_report(
    changes: list[tuple[int, str, str]], wanted: set[str], served: dict[str, list[str]]
) -> dict[str, set[str]]:
    """The changed units of each wanted report; a change of shared rows is a change of every report they serve."""
    grouped: dict[str, set[str]] = {}
    for _, kept, unit in changes:
        for name in served.get(kept, [kept]):
            if not wanted or name in wanted:
                grouped.setdefault(name, set()).add(unit)
    return grouped
