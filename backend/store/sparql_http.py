"""Any SPARQL 1.1 store reached over HTTP (Protocol for queries, Update for writes)."""

from __future__ import annotations

import io
import logging
from collections.abc import Callable, Iterator, Sequence
from itertools import islice
from typing import IO, cast

import httpx
from pyoxigraph import QueryResultsFormat, QuerySolutions, RdfFormat, parse, parse_query_results

from segb_server.backend.store.base import (
    Bindings,
    Quad,
    QueryResult,
    QueryTimeout,
    StoreCredentialsRefused,
    StoreError,
    StoreFenced,
    StoreRejectedQuery,
    StoreUnavailable,
)
from segb_server.backend.store.cursor_graph import CursorGraph, newest, refusal
from segb_server.backend.store.query_form import query_form
from segb_server.backend.store.terms import bind_values, term_text

logger = logging.getLogger("segb.store")

RESULTS_JSON = "application/sparql-results+json"
RESULTS_XML = "application/sparql-results+xml"
N_TRIPLES = "application/n-triples"
WRITE_BATCH_TRIPLES = 500  # well under Virtuoso's SP031 limit, and measured fastest there
# A time-limited query waits this much longer than its limit over HTTP, so a store that enforces the limit
# itself has time to say so.
HTTP_GRACE_SECONDS = 1.0


class SparqlHttpStore:
    """Generic adapter. Subclasses adjust authentication, dataset selection and the write path."""

    kind = "sparql"
    wraps_values = False
    max_sorted_rows: int | None = None
    remote = True
    # How SELECT and ASK answers are asked for and read: JSON, which every SPARQL 1.1 store writes.
    results_media_type = RESULTS_JSON
    results_format = QueryResultsFormat.JSON

    def __init__(
        self,
        *,
        query_endpoint: str,
        update_endpoint: str,
        graph_uri: str,
        auth: httpx.Auth | None = None,
        timeout_seconds: float = 30.0,
        ping_timeout_seconds: float = 1.0,
    ) -> None:
        self.graph_uri = graph_uri
        self.query_endpoint = query_endpoint
        self.update_endpoint = update_endpoint
        self._ping_timeout = ping_timeout_seconds
        self._client = httpx.Client(auth=auth, timeout=timeout_seconds)

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
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error
        if response.status_code in (401, 403):
            raise StoreCredentialsRefused(self._credentials_refused(response.status_code))
        if response.status_code != 200:
            raise StoreUnavailable(f"{self.kind} answered HTTP {response.status_code} to a ping")

    def _credentials_refused(self, status: int) -> str:
        """What to tell the operator when the store answers 401 or 403 (subclasses name their settings)."""
        return f"{self.kind} refused the server's credentials (HTTP {status}): check SPARQL_USER and SPARQL_PASSWORD"

    # --- writes --------------------------------------------------------------------------------------

    # With an apply epoch, the store's epoch is read before each request of triples, and the cursor is written by
    # an update that holds only while the store has seen no newer epoch (`cursor_graph.py`). The triples go as
    # INSERT DATA: the same 500 triples as an INSERT template under that condition took Virtuoso 7 six times as long.

    def apply(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        # INSERT DATA of a triple the graph holds changes nothing, so re-applying after a crash is harmless;
        # the cursor is written after the triples, so a crash in between only makes them applied twice.
        self._write_data("INSERT", quads, epoch)
        self._record(through, epoch)

    def _write_data(self, operation: str, quads: Sequence[Quad], epoch: int | None) -> None:
        graph = f"<{self.graph_uri}>"
        for start in range(0, len(quads), WRITE_BATCH_TRIPLES):
            body = "".join(
                f"{term_text(q.subject)} {q.predicate} {term_text(q.object)} .\n"
                for q in quads[start : start + WRITE_BATCH_TRIPLES]
            )
            if epoch is not None:
                self._refuse_if_newer(epoch)
            self._update(f"{operation} DATA {{ GRAPH {graph} {{\n{body}}} }}")

    def remove(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        # DELETE DATA of a triple the graph lacks changes nothing: a crash before the cursor only repeats it.
        # The store reads each literal as it did on INSERT DATA, so the triple is found in its own spelling.
        self._write_data("DELETE", quads, epoch)
        self._record(through, epoch)

    def clear(self, through: int | None = None, epoch: int | None = None) -> int:
        removed = self.count()
        if epoch is not None:  # CLEAR takes no WHERE: the epoch is checked just before, and recorded after
            self._refuse_if_newer(epoch)
        self._update(f"CLEAR SILENT GRAPH <{self.graph_uri}>")
        if through is not None:
            self._record(through, epoch)
        elif epoch is not None:
            self.claim(epoch)
        return removed

    def claim(self, epoch: int) -> None:
        self._update(self._cursors.claim(epoch))
        self._refuse_if_newer(epoch)

    def _refuse_if_newer(self, epoch: int) -> None:
        newer = self._newest_epoch()
        if newer is not None and newer > epoch:
            raise StoreFenced(epoch, newer)

    # The answers are read in functions of their own: a StoreFenced raised beside one would keep it in its
    # traceback, and pyoxigraph's answers must not be dropped by another thread than the one that read them.

    def _newest_epoch(self) -> int | None:
        solutions = self._query_raw(self._cursors.newest_epoch(), dataset=False)
        assert isinstance(solutions, QuerySolutions)
        return newest(solutions)

    def _refusal(self, through: int, epoch: int) -> int | None:
        held = self._query_raw(self._cursors.held(), dataset=False)
        assert isinstance(held, QuerySolutions)
        return refusal(held, through, epoch)

    def applied_through(self) -> int | None:
        solutions = self._query_raw(self._cursors.cursors(), dataset=False)
        assert isinstance(solutions, QuerySolutions)
        cursors = [int(row["n"].value) for row in solutions]
        return max(cursors) if cursors else None

    @property
    def cursor_graph(self) -> str:
        """Where the cursor lives: a graph of its own beside the events graph (queries never see it)."""
        return self._cursors.iri

    @property
    def _cursors(self) -> CursorGraph:
        return CursorGraph(self.graph_uri)

    def _record(self, through: int, epoch: int | None) -> None:
        self._update(self._cursors.record(through, epoch))
        if epoch is None:
            return
        # A refused update answers like any other: whether it took effect is read back.
        if (newer := self._refusal(through, epoch)) is not None:
            raise StoreFenced(epoch, newer)

    def _update(self, sparql_update: str) -> httpx.Response:
        response = self._send(
            self.update_endpoint,
            content=sparql_update.encode("utf-8"),
            headers={"Content-Type": "application/sparql-update; charset=utf-8", "Accept": RESULTS_JSON},
        )
        try:
            self._raise_for_status(response)
        except StoreRejectedQuery as refused:  # our own update: the caller's input is not at fault
            logger.warning("%s refused an update: %s", self.kind, refused)
            raise StoreError(f"{self.kind} refused to write the triples (the server log has its answer)") from None
        return response

    # --- reads ---------------------------------------------------------------------------------------

    def count(self) -> int:
        return self._select_count("SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }", dataset=True)

    def _select_count(self, sparql: str, dataset: bool = False) -> int:
        solutions = self.query(sparql) if dataset else self._query_raw(sparql, dataset=False)
        row = next(iter(solutions))  # type: ignore[arg-type]
        return int(row["n"].value)

    def query(self, sparql: str, bindings: Bindings | None = None, timeout: float | None = None) -> QueryResult:
        return self._query_raw(bind_values(sparql, bindings), dataset=True, timeout=timeout)

    def _query_raw(self, sparql: str, *, dataset: bool, timeout: float | None = None) -> QueryResult:
        form = query_form(sparql)
        if form is None:
            raise StoreRejectedQuery("not a SELECT, CONSTRUCT, ASK or DESCRIBE query")
        graph_form = form in ("construct", "describe")
        data = self._query_params(sparql, dataset)
        headers = {"Accept": N_TRIPLES if graph_form else self.results_media_type}
        body: bytes | _ByteStream
        if timeout is None:
            response = self._send(self.query_endpoint, data=data, headers=headers)
            self._raise_for_status(response)
            body = response.content
        else:
            body = self._open_stream({**data, **self._timeout_params(timeout)}, headers, timeout)
        if graph_form:
            return iter(quad.triple for quad in parse(_readable(body), RdfFormat.N_TRIPLES))
        result = parse_query_results(_readable(body), self.results_format)
        if form == "ask" and isinstance(result, QuerySolutions):
            # Virtuoso 7 answers ASK as a one-column SELECT (`__ASK_RETVAL`), one row when the answer is true.
            truth = any(getattr(row[0], "value", "1") not in ("0", "false") for row in result)
            return parse_query_results(
                b'{"head":{},"boolean":%s}' % str(truth).lower().encode(), QueryResultsFormat.JSON
            )
        return result

    def _open_stream(self, data: dict[str, str], headers: dict[str, str], timeout: float) -> _ByteStream:
        """Send a time-limited query and hand back its answer as a stream the parser reads on demand, so the
        reader can stop (and the connection close) at its row cap or deadline."""
        request = self._client.build_request(
            "POST", self.query_endpoint, data=data, headers=headers, timeout=timeout + HTTP_GRACE_SECONDS
        )
        try:
            response = self._client.send(request, stream=True)
        except httpx.ConnectTimeout as error:
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error
        except httpx.TimeoutException as error:
            raise QueryTimeout(timeout) from error
        except httpx.HTTPError as error:
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error
        if response.status_code >= 400 or self._timed_out(response):
            response.read()
            response.close()
            self._raise_for_status(response)
            raise QueryTimeout(timeout)
        return _ByteStream(response.iter_bytes(), on_close=response.close, timeout=timeout)

    def _timeout_params(self, timeout: float) -> dict[str, str]:
        """Protocol parameters asking the store itself to stop a query after `timeout` seconds (none in
        SPARQL 1.1; subclasses add their store's own)."""
        return {}

    def _refuses_the_query(self, message: str) -> bool:
        """Whether an error answer other than a 400 blames the query itself (subclasses know their store's)."""
        return False

    def _timed_out(self, response: httpx.Response) -> bool:
        """Whether a successful answer says the store stopped the query at its time limit."""
        return False

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
                quads = parse(_readable(_ByteStream(response.iter_bytes())), RdfFormat.N_TRIPLES)
                while batch := list(islice(quads, size)):
                    yield batch
        except httpx.HTTPError as error:
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error

    # --- plumbing ------------------------------------------------------------------------------------

    def _send(self, url: str, **kwargs: object) -> httpx.Response:
        try:
            return self._client.post(url, **kwargs)  # type: ignore[arg-type]
        except httpx.HTTPError as error:
            raise StoreUnavailable(f"{self.kind} does not answer: {error}") from error

    def _raise_for_status(self, response: httpx.Response) -> None:
        if response.status_code < 400:
            return
        text = self._summary(response.text)
        if response.status_code == 400 or self._refuses_the_query(text):
            raise StoreRejectedQuery(text)
        if response.status_code in (401, 403):
            raise StoreCredentialsRefused(self._credentials_refused(response.status_code))
        raise StoreError(f"{self.kind} answered HTTP {response.status_code}: {text}")

    def _summary(self, text: str) -> str:
        """What a store's error answer says, for people: its message without the query a store echoes after it
        (Virtuoso's "SPARQL query:"), without the graph's name, one line, bounded."""
        message = text.split("SPARQL query:", 1)[0]
        message = " ".join(message.split())[:300]
        return message.replace(self.graph_uri, "the events graph")

    def close(self) -> None:
        self._client.close()


def _readable(body: bytes | _ByteStream) -> bytes | IO[bytes]:
    """What pyoxigraph's parsers read: bytes, or a stream (a raw reader is a binary file to them)."""
    return body if isinstance(body, bytes) else cast(IO[bytes], body)


class _ByteStream(io.RawIOBase):
    """A readable file over an iterator of byte chunks, so the parser can consume a streamed response.

    `on_close` releases the response (at the end of the data, or when the parser is dropped early); with
    `timeout`, an HTTP wait running out while reading is a QueryTimeout."""

    def __init__(
        self, chunks: Iterator[bytes], on_close: Callable[[], None] | None = None, timeout: float | None = None
    ) -> None:
        self._chunks = chunks
        self._buffer = b""
        self._on_close = on_close
        self._timeout = timeout

    def readable(self) -> bool:
        return True

    def close(self) -> None:
        if self._on_close is not None:
            self._on_close()
            self._on_close = None
        super().close()

    def _next_chunk(self) -> bytes | None:
        try:
            return next(self._chunks, None)
        except httpx.TimeoutException as error:
            if self._timeout is None:
                raise
            raise QueryTimeout(self._timeout) from error
        except httpx.HTTPError as error:
            if self._timeout is None:
                raise
            raise StoreUnavailable(f"the store stopped answering: {error}") from error

    def readinto(self, target: bytearray | memoryview) -> int:  # type: ignore[override]
        while not self._buffer:
            chunk = self._next_chunk()
            if chunk is None:
                if self._on_close is not None:
                    self._on_close()
                    self._on_close = None
                return 0
            self._buffer = chunk
        size = min(len(target), len(self._buffer))
        target[:size] = self._buffer[:size]
        self._buffer = self._buffer[size:]
        return size
