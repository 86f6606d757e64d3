"""Asking the server's /sparql endpoint in tests."""

from __future__ import annotations

from tests.support.in_process import Server, http


def select_bindings(server: Server, query: str) -> list[dict[str, dict[str, str]]]:
    """The SPARQL JSON bindings of a SELECT run through `GET /sparql` (a live server's URL or an in-process
    app's client)."""
    response = http(
        server, "GET", "/sparql", params={"query": query}, headers={"Accept": "application/sparql-results+json"}
    )
    assert response.status_code == 200, response.text
    return response.json()["results"]["bindings"]
