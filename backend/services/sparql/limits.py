"""Running a user's SPARQL within a time limit and a row cap, the same way on every store."""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from itertools import islice
from typing import Any, TypeVar

from pyoxigraph import QueryBoolean, QueryResultsFormat, QuerySolutions, Triple, parse_query_results

from segb_server.backend.store.base import QueryResult, QueryTimeout, Store, StoreError
from segb_server.backend.store.terms import term_text

Item = TypeVar("Item")


@dataclass(frozen=True)
class QueryLimits:
    """How long a user's query may take, checking included, and how many rows its answer may hold. The time
    counts from when the limits are made (`started`, time.monotonic())."""

    timeout_seconds: float
    max_rows: int
    started: float = field(default_factory=time.monotonic)

    @property
    def deadline(self) -> float:
        return self.started + self.timeout_seconds

    def seconds_left(self) -> float:
        """What is left of the time; raise QueryTimeout when nothing is."""
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise QueryTimeout(self.timeout_seconds)
        return left


@dataclass(frozen=True)
class LimitedResult:
    """An answer of at most `max_rows` rows (or triples); `truncated` when the query had more."""

    result: QuerySolutions | QueryBoolean | list[Triple]
    truncated: bool
    rows: int


def run_limited(store: Store, sparql: str, limits: QueryLimits) -> LimitedResult:
    """Run `sparql` and read at most `limits.max_rows` rows of it before `limits.deadline`; raise QueryTimeout
    otherwise.

    The deadline is checked between rows: the embedded store cannot be interrupted, but it yields solutions
    lazily, so a query producing many rows stops at the first row past the deadline (one that computes long
    before its first row, like an ORDER BY over a huge join, is caught only when that row comes)."""
    try:
        result = store.query(sparql, timeout=limits.seconds_left())
    except QueryTimeout:
        raise QueryTimeout(limits.timeout_seconds) from None  # the store knew only the time left
    try:
        return _read(result, limits.deadline, limits)
    except StoreError as error:
        failure = QueryTimeout(limits.timeout_seconds) if isinstance(error, QueryTimeout) else error
    # pyoxigraph results must be dropped on the thread that made them, and the error's traceback holds
    # frames that hold them: let both go here, and raise the error with a fresh traceback.
    del result
    raise failure.with_traceback(None)


def _read(result: QueryResult, deadline: float, limits: QueryLimits) -> LimitedResult:
    if isinstance(result, QueryBoolean):
        _check(deadline, limits.timeout_seconds)
        return LimitedResult(result, truncated=False, rows=0)
    wanted = limits.max_rows + 1  # one more than allowed tells whether there were more
    if isinstance(result, QuerySolutions):
        read = list(islice(_before(deadline, limits.timeout_seconds, result), wanted))
        kept = read[: limits.max_rows]
        return LimitedResult(solutions_of(result.variables, kept), truncated=len(read) > len(kept), rows=len(kept))
    triples = list(islice(_before(deadline, limits.timeout_seconds, result), wanted))
    kept_triples = triples[: limits.max_rows]
    return LimitedResult(kept_triples, truncated=len(triples) > len(kept_triples), rows=len(kept_triples))


def _before(deadline: float, seconds: float, items: Iterable[Item]) -> Iterator[Item]:
    for item in items:
        _check(deadline, seconds)
        yield item


def _check(deadline: float, seconds: float) -> None:
    if time.monotonic() > deadline:
        raise QueryTimeout(seconds)


def solutions_of(variables: Sequence[Any], rows: Sequence[Any]) -> QuerySolutions:
    """Rows read (QuerySolution objects, or sequences of terms) as a QuerySolutions again, so pyoxigraph's own
    writers serialise them: pyoxigraph cannot build one from a list, but it parses SPARQL TSV, whose terms are
    what `term_text` writes."""
    names = [variable.value for variable in variables]
    lines = ["\t".join(f"?{name}" for name in names)]
    lines.extend("\t".join("" if term is None else term_text(term) for term in row) for row in rows)
    return parse_query_results(("\n".join(lines) + "\n").encode("utf-8"), QueryResultsFormat.TSV)  # type: ignore[return-value]
