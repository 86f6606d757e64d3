"""Concurrent queries: rdflib's SPARQL parser (pyparsing) is not thread-safe, and once two threads parse at
once it stays broken for every later query. The reference UI's reports page alone sends seven at once."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

from tests.support.in_process import InProcess
from tests.support.scenarios import lobby

PREFIXED = "PREFIX ex: <http://e/> SELECT ?s WHERE {{ ?s ex:p ?o FILTER (?o != <http://e/{n}>) }} LIMIT 1"
FORMS = [
    "SELECT (COUNT(*) AS ?n) WHERE {{ ?s ?p ?o FILTER (?o != {n}) }}",
    "PREFIX schema: <http://schema.org/> ASK {{ ?m schema:text ?t FILTER (STRLEN(?t) > {n}) }}",
    "PREFIX prov: <http://www.w3.org/ns/prov#> CONSTRUCT {{ ?a prov:wasAssociatedWith ?r }} "
    "WHERE {{ ?a prov:wasAssociatedWith ?r }} LIMIT {n}",
]


def requests_for(index: int) -> tuple[str, str, dict[str, object]]:
    """A mix of every way a query reaches the parser; each text is new, so no parse is served from a cache."""
    text = (PREFIXED if index % 2 else FORMS[index % 3]).format(n=index + 1)
    kind = index % 5
    if kind == 0:
        return "GET", "/sparql", {"params": {"query": text}}
    if kind == 1:
        return "POST", "/sparql", {"data": {"query": text}}
    if kind == 2:
        return "GET", "/query", {"params": {"query": text}}
    if kind == 3:
        return "POST", "/query/validate", {"json": {"query": text}}
    return "GET", "/reports/conversations", {"params": {"limit": 1 + index}}


def test_fifty_concurrent_mixed_queries_all_succeed_and_parsing_still_works(memory_api: InProcess) -> None:
    lobby().publish_all(memory_api.client)
    client = memory_api.client

    def send(index: int) -> tuple[int, str]:
        method, path, arguments = requests_for(index)
        answer = client.request(method, path, **arguments)  # type: ignore[arg-type]
        return answer.status_code, answer.text[:200]

    with ThreadPoolExecutor(max_workers=50) as pool:
        answers = list(pool.map(send, range(50)))
    assert [answer for answer in answers if answer[0] != 200] == []
    assert all('"valid":true' in text for status, text in answers[3::5])

    after = client.get("/sparql", params={"query": PREFIXED.format(n=0)})
    assert after.status_code == 200, after.text
