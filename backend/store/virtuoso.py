"""Virtuoso over its digest-authenticated SPARQL endpoint (`/sparql-auth`)."""

from __future__ import annotations

import httpx
from pyoxigraph import QueryResultsFormat

from segb_server.backend.store.sparql_http import RESULTS_XML, SparqlHttpStore


class VirtuosoStore(SparqlHttpStore):
    """Virtuoso's digest-authenticated endpoint, its own query time limit ("anytime" queries) and the state
    it reports them with."""

    kind = "virtuoso"
    wraps_values = True
    max_sorted_rows: int | None = 10_000  # its default MaxSortedTopRows
    # Virtuoso 7 writes XML answers five times faster than JSON ones (2,000 rows: 30 ms against 168 ms,
    # docs/performance.md), and the views' upkeep and explanations read many rows. Its XML writer ends a
    # literal at a U+0000 character, which XML cannot hold; the journal keeps such a literal whole.
    results_media_type = RESULTS_XML
    results_format = QueryResultsFormat.XML

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
        self.user = user
        super().__init__(
            query_endpoint=endpoint,
            update_endpoint=endpoint,
            graph_uri=graph_uri,
            auth=httpx.DigestAuth(user, password),
            timeout_seconds=timeout_seconds,
            ping_timeout_seconds=ping_timeout_seconds,
        )

    def _credentials_refused(self, status: int) -> str:
        if status != 401:
            return f"Virtuoso refused user {self.user} (HTTP {status}): it needs the SPARQL_UPDATE role"
        return (
            f"Virtuoso refused the password of user {self.user} (HTTP 401): VIRTUOSO_PASSWORD is not that "
            "account's password. Virtuoso keeps the password its database was created with (in docker compose: "
            "when the virtuoso-data volume was created), so changing VIRTUOSO_PASSWORD later does not change it. "
            f"Set VIRTUOSO_PASSWORD back to that password, or change it in Virtuoso "
            f"(isql: user_set_password('{self.user}', '<new password>'))"
        )

    def _timeout_params(self, timeout: float) -> dict[str, str]:
        return {"timeout": str(max(1, round(timeout * 1000)))}  # milliseconds ("anytime" queries)

    def _refuses_the_query(self, message: str) -> bool:
        # A 500 all the same: a sorted LIMIT (offset included) past the rows it sorts, MaxSortedTopRows.
        return "SR353" in message

    def _timed_out(self, response: httpx.Response) -> bool:
        # An "anytime" answer is a 200 holding what was found before the time ran out, flagged by this state.
        return response.headers.get("x-sql-state") == "S1TAT"
