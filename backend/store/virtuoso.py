"""Virtuoso over its digest-authenticated SPARQL endpoint (`/sparql-auth`)."""

from __future__ import annotations

import httpx

from segb_server.backend.store.sparql_http import SparqlHttpStore


class VirtuosoStore(SparqlHttpStore):
    """Virtuoso's digest-authenticated endpoint, its own query time limit ("anytime" queries) and the state
    it reports them with."""

    kind = "virtuoso"
    wraps_values = True

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
