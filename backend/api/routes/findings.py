"""GET /rules, GET /findings and GET /findings/stream: the audit rules and what they find, as robots publish."""

from __future__ import annotations

import csv
import io
import json

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response, StreamingResponse

from segb_server.backend.api.deps import Auditor, ServicesDep
from segb_server.backend.api.responses import FastJSONResponse
from segb_server.backend.api.routes.live import ENDS_WITH_THE_TOKEN, event_stream
from segb_server.backend.services.csv_cells import spreadsheet_safe
from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.formats import TABLES, negotiate
from segb_server.backend.services.rules.service import DEFAULT_LIMIT, FILTERS, MAX_LIMIT, FindingsPage
from segb_server.backend.services.sparql.catalog import Parameter, to_term

router = APIRouter(tags=["findings"])

MAX_FOCUS = 200
CSV_COLUMNS = ("time", "rule", "severity", "robot", "human", "focus", "message", "values")


@router.get(
    "/rules",
    summary="The audit rules, with how many findings each has",
    description=(
        "Every rule of the rules folder (`RULES_DIR`): `id`, `title`, `severity` (violation, warning or info), "
        "`description`, `kind` (sparql or shacl), `file`, `parameters` with their defaults, and `findings`, how "
        "many it finds now; `counts` totals them by severity."
    ),
)
async def list_rules(services: ServicesDep, principal: Auditor) -> Response:
    findings = services.findings

    def work() -> dict[str, object]:
        counts = findings.counts(findings.selection({}))
        rules = [{**rule.describe(), "findings": counts["by_rule"][rule.id]} for rule in findings.catalog]
        return {"rules": rules, "counts": counts["by_severity"]}

    return FastJSONResponse(await run_in_threadpool(work))


@router.get(
    "/findings",
    summary="What the rules find, in time order",
    description=(
        "Findings of every rule (or of `rule`, `severity`: both repeatable), filtered by `robot`, `human` (IRIs), "
        "`since`, `until` (ISO 8601 times with a zone, inclusive): a rule that does not declare a filter that is "
        "given has nothing to say under it and is left out. Each finding: `rule`, `severity`, `title`, `focus` "
        "(what it is about: open it with `/explain?iri=`), `about` (the focus as `GET /graph` draws it: `label`, "
        "`kind`, `types`, `time`; null while the graph does not hold it), `message`, `time`, `robot`, `human`, "
        "`values`. "
        "`focus=` (repeatable) lists every finding about those nodes instead, unpaged. "
        "`counts` gives the findings per rule and per severity under the same filters; `next` is the cursor of "
        "the next page (`after=`); `served_from` says, per rule, whether its findings come from its kept rows "
        "(`rows`), its query evaluated in full (`query`: a rule the rows cannot follow) or nothing yet: its "
        "findings are being first built (`building`; the SHACL rules' list those checked so far); `limit` 1 to "
        f"{MAX_LIMIT} (default {DEFAULT_LIMIT}). CSV with "
        "`Accept: text/csv` or `?format=csv`. `last_event_id`: where `GET /findings/stream` stands for these rows."
    ),
    responses={200: {"content": {"application/json": {}, "text/csv": {}}}, 422: {}},
)
async def list_findings(
    request: Request,
    services: ServicesDep,
    principal: Auditor,
    rule: list[str] = Query([], description="Only this rule's findings (repeatable)"),
    severity: list[str] = Query([], description="Only findings of this severity (repeatable)"),
    robot: str | None = Query(None, description="Only findings about this robot (IRI)"),
    human: str | None = Query(None, description="Only findings about this human (IRI)"),
    since: str | None = Query(None, description="Only findings at or after this time"),
    until: str | None = Query(None, description="Only findings at or before this time"),
    focus: list[str] = Query([], description=f"Only findings about this node (repeatable, at most {MAX_FOCUS})"),
    after: str | None = Query(None, description="The `next` cursor of the previous page"),
    format: str | None = Query(None, description="json or csv; overrides Accept"),
) -> Response:
    limit = _limit(request.query_params.get("limit"))
    fmt = negotiate(TABLES, request.headers.get("accept"), format, what="the findings")
    known = {"rule", "severity", "limit", "after", "format", "focus", *FILTERS}
    unknown = sorted(set(request.query_params) - known)
    if unknown:
        raise InvalidParameter(unknown[0], "not a filter of the findings")
    values = {name: request.query_params.getlist(name) for name in ("rule", "severity", *FILTERS)}

    if focus:
        return await _about(services, focus, set(request.query_params) - {"focus", "format"})

    def work() -> Response:
        findings = services.findings
        page = findings.page(findings.selection(values), limit, after)
        if fmt.name == "csv":
            return Response(
                _csv(page),
                media_type=fmt.content_type,
                headers={"Content-Disposition": 'attachment; filename="findings.csv"'},
            )
        nodes = services.graph.nodes({str(found["focus"]) for found in page.findings})
        return FastJSONResponse(_json(page, limit, nodes))

    return await run_in_threadpool(work)


@router.get(
    "/findings/stream",
    summary="Changes of the findings, live (Server-Sent Events)",
    description=(
        'An `event: change` with `data: {"rules": [...]}` whenever findings of those rules appeared or went; its '
        "`id` is the findings' position (as `last_event_id` of `GET /findings`). Fetch the findings again on each. "
        "With a `Last-Event-ID` other than the current position, one change is sent at once. A comment every 15 s "
        "keeps idle connections open." + ENDS_WITH_THE_TOKEN
    ),
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}},
)
async def findings_stream(request: Request, services: ServicesDep, principal: Auditor) -> StreamingResponse:
    findings = services.findings
    resume = request.headers.get("last-event-id", "")
    seen = await run_in_threadpool(findings.last_event_id)
    if resume and resume != seen:
        seen = ""  # a reader that missed something hears one change at once and reloads

    async def changes() -> list[bytes]:
        nonlocal seen
        current, rules = await run_in_threadpool(findings.changed_rules, seen)
        if current == seen:
            return []
        seen = current
        data = json.dumps({"rules": rules})
        return [f"id: {current}\nevent: change\ndata: {data}\n\n".encode()]

    async def opening() -> list[bytes]:
        return []

    return event_stream(request, opening, changes, findings.changed, principal.expires_at)


async def _about(services: ServicesDep, focus: list[str], others: set[str]) -> Response:
    """`focus=`: every finding about those nodes, whatever its rule (no paging: a handful of nodes)."""
    if others:
        raise InvalidParameter(sorted(others)[0], "`focus` lists the findings about nodes, with no other filter")
    if len(focus) > MAX_FOCUS:
        raise InvalidParameter("focus", f"at most {MAX_FOCUS} nodes")
    for iri in focus:
        to_term(Parameter("focus", "iri"), iri)  # 422 naming `focus` when it is not an IRI
    findings = await run_in_threadpool(services.findings.about, focus)
    return FastJSONResponse({"findings": findings, "has_more": False, "next": None})


def _limit(raw: str | None) -> int:
    if raw is None:
        return DEFAULT_LIMIT
    try:
        value = int(raw)
    except ValueError:
        raise InvalidParameter("limit", f"'{raw}' is not a whole number") from None
    if not 1 <= value <= MAX_LIMIT:
        raise InvalidParameter("limit", f"must be between 1 and {MAX_LIMIT}")
    return value


def _json(page: FindingsPage, limit: int, nodes: dict[str, dict[str, object]]) -> dict[str, object]:
    return {
        "findings": [{**found, "about": nodes.get(str(found["focus"]))} for found in page.findings],
        "counts": page.counts,
        "limit": limit,
        "has_more": page.has_more,
        "next": page.next,
        "served_from": page.served_from,
        "last_event_id": page.last_event_id,
    }


def _csv(page: FindingsPage) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\r\n")
    writer.writerow(CSV_COLUMNS)
    for found in page.findings:
        values = found.get("values") or {}
        writer.writerow(
            [
                *(
                    "" if found.get(column) is None else spreadsheet_safe(str(found.get(column)))
                    for column in CSV_COLUMNS[:-1]
                ),
                json.dumps(values, sort_keys=True) if values else "",  # starts with "{": never a formula
            ]
        )
    return buffer.getvalue()
