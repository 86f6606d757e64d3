"""Any SPARQL 1.1 store reached over HTTP (Protocol for queries, Update for writes)."""

from __future__ import annotations

import io
import logging
from collections.abc import Iterator, Sequence
from itertools import islice

import httpx
from pyoxigraph import QueryResultsFormat, QuerySolutions, RdfFormat, parse, parse_query_results

from backend.store.base import Bindings, Quad, QueryResult, StoreError, StoreRejectedQuery, StoreUnavailable
from backend.store.known_triples import KnownTriples, triple_key
from backend.store.query_form import query_form
from backend.store.terms import bind_values

logger = logging.getLogger("segb.store")

RESULTS_JSON = "application/sparql-results+json"
N_TRIPLES = "application/n-triples"
WRITE_BATCH_TRIPLES = 500  # well under Virtuoso's SP031 limit, and measured fastest there


class SparqlHttpStore:
    """Generic adapter. Subclasses adjust authentication, dataset selection and the write path."""

    kind = "sparql"

    def __init__(
        self,
        *,
        query_endpoint: str,
        update_endpoint: str,
        graph_uri: str,
        auth: httpx.Auth | None = None,
        timeout_seconds: float = 30.0,
        ping_timeout_seconds: float = 1.0,
        known_capacity: int = 1_000_000,
    ) -> None:
        self.graph_uri = graph_uri
        self.query_endpoint = query_endpoint
        self.update_endpoint = update_endpoint
        self._ping_timeout = ping_timeout_seconds
        self._client = httpx.Client(auth=auth, timeout=timeout_seconds)
        self._known = KnownTriples(known_capacity)
        self._was_down = False

    # --- health --------------------------------------------------------------------------------------

    def ping(self) -> None:
        try:
            response = self._client.post(
                self.query_endpoint,
                data={"query": "ASK {}"},
                headers={"Accept": RESULTS_JSON},
                timeout=self._ping_timeout,
            )
        except httpx.HTTPError as error:
            self._mark_down()
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error
        if response.status_code != 200:
            self._mark_down()
            raise StoreUnavailable(f"{self.kind} answered HTTP {response.status_code} to a ping")
        if self._was_down:
            # The store may have been restored or wiped while away: stop trusting what we knew of it.
            self._known.forget()
            self._was_down = False

    def _mark_down(self) -> None:
        self._was_down = True

    # --- writes --------------------------------------------------------------------------------------

    def insert_new(self, quads: Sequence[Quad]) -> int:
        candidates: dict[int, str] = {}
        known = self._known
        for quad in quads:
            line = f"{quad.subject} {quad.predicate} {quad.object}"
            key = triple_key(line)
            if key not in known:
                candidates[key] = line
        new = 0
        pending = iter(candidates.items())
        while batch := list(islice(pending, WRITE_BATCH_TRIPLES)):
            new += self._insert_missing([line for _, line in batch])
            known.remember(key for key, _ in batch)
        return new

    def _insert_missing(self, lines: list[str]) -> int:
        """Insert the triples that are not yet in the graph; return how many that was."""
        rows = "".join(f"({line})\n" for line in lines)
        present = self._select_count(
            f"SELECT (COUNT(*) AS ?n) WHERE {{ VALUES (?s ?p ?o) {{\n{rows}}}\n"
            f"  GRAPH <{self.graph_uri}> {{ ?s ?p ?o }} }}"
        )
        body = "".join(f"{line} .\n" for line in lines)
        self._update(f"INSERT DATA {{ GRAPH <{self.graph_uri}> {{\n{body}}} }}")
        return len(lines) - present

    def clear(self) -> int:
        removed = self.count()
        self._update(f"CLEAR SILENT GRAPH <{self.graph_uri}>")
        self._known.forget()
        return removed

    def _update(self, sparql_update: str) -> httpx.Response:
        response = self._send(
            self.update_endpoint,
            content=sparql_update.encode("utf-8"),
            headers={"Content-Type": "application/sparql-update; charset=utf-8", "Accept": RESULTS_JSON},
        )
        self._raise_for_status(response)
        return response

    # --- reads ---------------------------------------------------------------------------------------

    def count(self) -> int:
        return self._select_count("SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }", dataset=True)

    def _select_count(self, sparql: str, dataset: bool = False) -> int:
        solutions = self.query(sparql) if dataset else self._query_raw(sparql, dataset=False)
        row = next(iter(solutions))  # type: ignore[arg-type]
        return int(row["n"].value)

    def query(self, sparql: str, bindings: Bindings | None = None) -> QueryResult:
        return self._query_raw(bind_values(sparql, bindings), dataset=True)

    def _query_raw(self, sparql: str, *, dataset: bool) -> QueryResult:
        form = query_form(sparql)
        if form is None:
            raise StoreRejectedQuery("not a SELECT, CONSTRUCT, ASK or DESCRIBE query")
        graph_form = form in ("construct", "describe")
        response = self._send(
            self.query_endpoint,
            data=self._query_params(sparql, dataset),
            headers={"Accept": N_TRIPLES if graph_form else RESULTS_JSON},
        )
        self._raise_for_status(response)
        if graph_form:
            return iter(
                quad.triple
                for quad in parse(response.content, RdfFormat.N_TRIPLES)  # type: ignore[union-attr]
            )
        result = parse_query_results(response.content, QueryResultsFormat.JSON)
        if form == "ask" and isinstance(result, QuerySolutions):
            # Virtuoso 7 answers ASK as a one-column SELECT (`__ASK_RETVAL`), one row when the answer is true.
            truth = any(getattr(row[0], "value", "1") not in ("0", "false") for row in result)
            return parse_query_results(
                b'{"head":{},"boolean":%s}' % str(truth).lower().encode(), QueryResultsFormat.JSON
            )
        return result

    def _query_params(self, sparql: str, dataset: bool) -> dict[str, str]:
        params = {"query": sparql}
        if dataset:
            params["default-graph-uri"] = self.graph_uri
        return params

    def batches(self, size: int) -> Iterator[list[Quad]]:
        query = "CONSTRUCT { ?s ?p ?o } WHERE { ?s ?p ?o }"
        try:
            with self._client.stream(
                "POST",
                self.query_endpoint,
                data=self._query_params(query, True),
                headers={"Accept": N_TRIPLES},
            ) as response:
                if response.status_code >= 400:
                    response.read()
                    self._raise_for_status(response)
                quads = parse(_ByteStream(response.iter_bytes()), RdfFormat.N_TRIPLES)
                while batch := list(islice(quads, size)):
                    yield batch  # type: ignore[misc]
        except httpx.HTTPError as error:
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error

    # --- plumbing ------------------------------------------------------------------------------------

    def _send(self, url: str, **kwargs: object) -> httpx.Response:
        try:
            return self._client.post(url, **kwargs)  # type: ignore[arg-type]
        except httpx.HTTPError as error:
            self._mark_down()
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error

    def _raise_for_status(self, response: httpx.Response) -> None:
        if response.status_code < 400:
            return
        text = response.text.strip()[:600]
        if response.status_code == 400:
            raise StoreRejectedQuery(text)
        if response.status_code in (401, 403):
            raise StoreError(f"{self.kind} refused the server's credentials (HTTP {response.status_code})")
        raise StoreError(f"{self.kind} answered HTTP {response.status_code}: {text}")

    def close(self) -> None:
        self._client.close()


class _ByteStream(io.RawIOBase):
    """A readable file over an iterator of byte chunks, so the parser can consume a streamed response."""

    def __init__(self, chunks: Iterator[bytes]) -> None:
        self._chunks = chunks
        self._buffer = b""

    def readable(self) -> bool:
        return True

    def readinto(self, target: bytearray | memoryview) -> int:  # type: ignore[override]
        while not self._buffer:
            chunk = next(self._chunks, None)
            if chunk is None:
                return 0
            self._buffer = chunk
        size = min(len(target), len(self._buffer))
        target[:size] = self._buffer[:size]
        self._buffer = self._buffer[size:]
        return size
