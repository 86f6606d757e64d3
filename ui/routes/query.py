"""/query: the SPARQL workbench. An editor prefilled with the known prefixes, example queries, the answer as a
table whose IRIs lead to /explain and /kg-graph, and downloads relayed from the API's /sparql."""

from __future__ import annotations

from typing import Any

import anyio
from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, Response

from segb_server.ui.api_client import BackendClient, BackendError
from segb_server.ui.pages import backend, render, token
from segb_server.ui.query_results import Table, from_ntriples, from_results_json

router = APIRouter()

SHOWN_ROWS = 1000  # the page shows this many; the downloads carry the whole answer
GRAPH_FORMS = ("construct", "describe")
# Download suffix → (the API's `format`, the file's media type).
DOWNLOADS = {
    "csv": ("csv", "text/csv; charset=utf-8"),
    "json": ("json", "application/sparql-results+json"),
    "ttl": ("turtle", "text/turtle; charset=utf-8"),
}


@router.get("/query", response_class=HTMLResponse)
async def query_page(request: Request) -> HTMLResponse:
    client, user_token = backend(request), token(request)
    offered = await client.get_json("/sparql/examples", token=user_token)
    examples = offered["examples"]
    text = request.query_params.get("query", "")
    asked = request.query_params.get("example")
    # The example the editor's text came from: the one named, else the one whose text it still is.
    chosen = next((e for e in examples if e["name"] == asked), None) or next(
        (e for e in examples if text.strip() and e["query"].strip() == text.strip()), None
    )
    context: dict[str, Any] = {"examples": examples, "example": chosen["name"] if chosen else ""}
    if text.strip():
        context.update(await _run(client, user_token, text))
    context["text"] = text or (chosen or examples[0])["query"]
    return render(request, "query.html", context)


async def _run(client: BackendClient, user_token: str | None, text: str) -> dict[str, Any]:
    """Check the query first (the check gives line and column), then run it; failures become page text."""
    check = await client.post_json("/query/validate", {"query": text}, token=user_token)
    if not check["valid"]:
        return {"error": check}
    form = check["form"]
    try:
        answer = await client.sparql(text, "ntriples" if form in GRAPH_FORMS else "json", token=user_token)
    except BackendError as error:
        if error.status in (401, 403):
            raise
        return {"error": {"message": error.detail, "status": error.status}}

    def tabulate() -> Table:
        return from_ntriples(answer.content) if form in GRAPH_FORMS else from_results_json(answer.json())

    # Parsing a long answer is CPU work: keep it off the event loop.
    table = await anyio.to_thread.run_sync(tabulate)
    return {
        "form": form,
        "table": table,
        "shown": table.rows[:SHOWN_ROWS],
        "truncated": answer.headers.get("x-segb-truncated") == "true",
        "max_rows": answer.headers.get("x-segb-max-rows"),
    }


@router.get("/query/download.{suffix}")
async def download_answer(request: Request, suffix: str) -> Response:
    """The whole answer as a file, fetched with the viewer's token (the browser never talks to the API)."""
    if suffix not in DOWNLOADS:
        return Response("Downloads are .csv, .json or .ttl", status_code=404, media_type="text/plain")
    fmt, media_type = DOWNLOADS[suffix]
    answer = await backend(request).sparql(request.query_params.get("query", ""), fmt, token=token(request))
    headers = {"Content-Disposition": f'attachment; filename="query.{suffix}"'}
    if "x-segb-truncated" in answer.headers:
        headers["X-SEGB-Truncated"] = answer.headers["x-segb-truncated"]
    return Response(answer.content, media_type=media_type, headers=headers)
