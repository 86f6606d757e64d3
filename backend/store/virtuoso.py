"""Virtuoso over its digest-authenticated SPARQL endpoint (`/sparql-auth`)."""

from __future__ import annotations

import re

import httpx

from segb_server.backend.store.base import StoreError
from segb_server.backend.store.sparql_http import SparqlHttpStore

# Virtuoso reports what a SPARQL update did as a one-cell result, e.g.
# "Insert into <http://amor-segb/events>, 57 (or less) triples -- done".
_INSERTED = re.compile(r"Insert into <[^>]*>, (\d+) ")


class VirtuosoStore(SparqlHttpStore):
    """Writes use one conditional INSERT per batch: the count Virtuoso reports is exactly the number of
    triples that were missing, so a post costs one round trip per 500 unknown triples (measured against
    INSERT DATA batches and the graph-store endpoint in docs/performance.md)."""

    kind = "virtuoso"

    def __init__(
        self,
        *,
        endpoint: str,
        user: str,
        password: str,
        graph_uri: str,
        timeout_seconds: float = 30.0,
        ping_timeout_seconds: float = 1.0,
    ) -> None:
        super().__init__(
            query_endpoint=endpoint,
            update_endpoint=endpoint,
            graph_uri=graph_uri,
            auth=httpx.DigestAuth(user, password),
            timeout_seconds=timeout_seconds,
            ping_timeout_seconds=ping_timeout_seconds,
        )

    def _timeout_params(self, timeout: float) -> dict[str, str]:
        return {"timeout": str(max(1, round(timeout * 1000)))}  # milliseconds ("anytime" queries)

    def _timed_out(self, response: httpx.Response) -> bool:
        # An "anytime" answer is a 200 holding what was found before the time ran out, flagged by this state.
        return response.headers.get("x-sql-state") == "S1TAT"

    def _insert_missing(self, lines: list[str]) -> int:
        rows = "".join(f"({line})\n" for line in lines)
        graph = f"<{self.graph_uri}>"
        response = self._update(
            f"INSERT {{ GRAPH {graph} {{ ?s ?p ?o }} }}\n"
            f"WHERE {{ VALUES (?s ?p ?o) {{\n{rows}}}\n"
            f"  FILTER NOT EXISTS {{ GRAPH {graph} {{ ?s ?p ?o }} }} }}"
        )
        reported = _INSERTED.search(response.text)
        if reported is None:
            raise StoreError(f"unexpected answer from Virtuoso to an insert: {response.text[:300]}")
        return int(reported.group(1))
