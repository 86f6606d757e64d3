"""The port between services and triple stores: one small protocol and the result shapes it returns."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from pyoxigraph import BlankNode, Literal, NamedNode, Quad, QueryBoolean, QuerySolutions, Triple

from segb_server.backend.store.query_form import is_distinct
from segb_server.backend.store.solutions import read_whole

Term = NamedNode | BlankNode | Literal
Bindings = Mapping[str, Term | None]
QueryResult = QuerySolutions | QueryBoolean | Iterator[Triple]


# How far the journal has been applied: one triple `CURSOR_SUBJECT CURSOR_PREDICATE <sequence>` that every
# adapter keeps beside the events graph, written with the triples (see Store.apply).
CURSOR_SUBJECT = NamedNode("urn:segb:journal")
CURSOR_PREDICATE = NamedNode("urn:segb:appliedThrough")
# Beside it, with several hosts applying in turn (a shared PostgreSQL state): the newest apply leadership's epoch
# that wrote the store. A write of an older epoch is refused (`StoreFenced`): its leader lost the lead meanwhile.
EPOCH_PREDICATE = NamedNode("urn:segb:appliedByEpoch")


class StoreError(Exception):
    """A store failed in a way the caller cannot fix by changing its input."""


class StoreFenced(Exception):
    """A write of an apply leadership's epoch older than the one the store has seen: its writer lost the lead (and
    another process applies now), so it must stop applying. Not a StoreError: retrying would never succeed."""

    def __init__(self, epoch: int, newer: int) -> None:
        super().__init__(f"the store was written by apply epoch {newer}, newer than this writer's {epoch}")
        self.epoch, self.newer = epoch, newer


class StoreUnavailable(StoreError):
    """The store does not answer (down, unreachable, timing out)."""


class StoreCredentialsRefused(StoreError):
    """The store refused the server's user or password: a setting to correct, not an outage that passes."""


class StoreRejectedQuery(StoreError):
    """The store refused a query as invalid; the message says why."""


class QueryTimeout(StoreError):
    """A user query ran past its time limit (the store's own limit, the HTTP wait, or the reading deadline)."""

    def __init__(self, seconds: float) -> None:
        super().__init__(
            f"The query ran longer than {seconds:g} s (SPARQL_TIMEOUT_SECONDS) and was stopped; "
            "narrow it down or add a LIMIT."
        )
        self.seconds = seconds


@dataclass(frozen=True)
class SelectResult:
    """Rows of a SELECT query, in the store's order, with the projected column names."""

    columns: list[str]
    rows: list[dict[str, Term]] = field(default_factory=list)


class Store(Protocol):
    """What every triple store adapter offers. Events live in one graph, `graph_uri`."""

    kind: str
    graph_uri: str
    # A VALUES block of several rows wraps the WHERE group instead of opening it (`bind_rows`): Virtuoso 7 skips
    # FILTERs of a group that opens with one. Elsewhere it opens the group, so the store joins from it.
    wraps_values: bool
    # Queries wait on the network (a SPARQL server), not on this process's cores: several at once finish sooner.
    remote: bool
    # The most rows the store sorts for one answer with a LIMIT, OFFSET included (Virtuoso's MaxSortedTopRows:
    # past it, error SR353); None when there is no such bound. A deeper page is read from the answer in full.
    max_sorted_rows: int | None

    def ping(self) -> None:
        """Raise StoreUnavailable unless the store answers a trivial query."""

    def apply(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        """Add the quads (any graph name is ignored) to the events graph, idempotently, and record that the
        journal is applied through entry `through` (in the same transaction where the store has them).
        `epoch`: the writer's apply leadership epoch; refused (StoreFenced) when the store has seen a newer one,
        and recorded with the cursor. None: the only writer there is (no shared leadership)."""

    def remove(self, quads: Sequence[Quad], through: int, epoch: int | None = None) -> None:
        """Remove the quads (as received: the store finds them in its own spelling) from the events graph, keep
        nothing of them in the store's files where the store can manage that, and record that the journal is
        applied through `through`. Re-applying is harmless. `epoch`: as for `apply`."""

    def clear(self, through: int | None = None, epoch: int | None = None) -> int:
        """Remove every triple of the events graph (recording `through` as applied, when given); return how
        many there were. `epoch`: as for `apply`."""

    def claim(self, epoch: int) -> None:
        """Record that apply epoch `epoch` writes the store from now on: every write of an older one is refused.
        Raises StoreFenced when the store has seen a newer epoch already."""

    def applied_through(self) -> int | None:
        """The journal entry this store is applied through, or None when it holds no record of it (a store
        from before the journal, or a new or wiped one)."""

    def count(self) -> int:
        """Number of triples in the events graph."""

    def query(self, sparql: str, bindings: Bindings | None = None, timeout: float | None = None) -> QueryResult:
        """Run a read-only query over the events graph (as default graph), with optional bound values.

        With `timeout`, a remote store is asked to stop after that many seconds and the answer is streamed,
        so the caller can stop reading at its own deadline; the embedded store cannot be interrupted and
        relies on the caller's deadline alone (segb_server.backend.services.sparql.limits)."""

    def batches(self, size: int) -> Iterator[list[Quad]]:
        """Stream the events graph as lists of at most `size` quads (in the default graph)."""

    def close(self) -> None:
        """Release connections and files."""


def select(store: Store, sparql: str, bindings: Bindings | None = None) -> SelectResult:
    """Run a SELECT and materialise its rows as dicts of terms (unbound columns are left out of a row)."""
    solutions = store.query(sparql, bindings)
    if not isinstance(solutions, QuerySolutions):
        raise TypeError("select() needs a SELECT query")
    return rows_of(sparql, solutions)


def rows_of(sparql: str, solutions: QuerySolutions) -> SelectResult:
    """The rows of a store's answer to `sparql`, read whole (`read_whole`). A SELECT DISTINCT answer is made
    distinct here too: Virtuoso 7 answers some DISTINCT queries (OPTIONALs and BINDs over EXISTS) with repeated
    solutions, depending on the plan its statistics choose."""
    columns, answer = read_whole(solutions)
    rows = []
    seen: set[tuple[object, ...]] = set()
    distinct = is_distinct(sparql)
    for values in answer:
        if distinct:
            if values in seen:
                continue
            seen.add(values)
        rows.append({name: value for name, value in zip(columns, values, strict=True) if value is not None})
    return SelectResult(columns=columns, rows=rows)  # type: ignore[arg-type]
