"""Asking the server's /sparql endpoint in tests."""

from __future__ import annotations

import httpx


def select_bindings(base_url: str, query: str) -> list[dict[str, dict[str, str]]]:
    """The SPARQL JSON bindings of a SELECT run through `GET /sparql`."""
    response = httpx.get(
        f"{base_url}/sparql",
        params={"query": query},
        headers={"Accept": "application/sparql-results+json"},
        timeout=30,
    )
    assert response.status_code == 200, response.text
    return response.json()["results"]["bindings"]
