"""The knowledge graph as nodes and edges for drawing (from the graph index), and everything about one
resource (from the store).

`GET /graph` reads `GraphIndex`, the drawable graph kept as indexed rows from the journal's stream: its
cost does not grow with the log. Literals only name and place nodes; the rest are details fetched per node
(`resource`), with two small bound queries (`sparql/graph/resource-*.rq`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from concurrent.futures import ThreadPoolExecutor

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.reading import own_time
from segb_server.backend.services.errors import InvalidParameter, ViewNotReady
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, Catalog, paged
from segb_server.backend.services.values import json_value
from segb_server.backend.services.views.graph_index import (
    CATEGORY,
    GENERATED_AT,
    RDF_TYPE,
    GraphIndex,
    GraphRequest,
    display_label,
    local_name,
)
from segb_server.backend.store.base import Store, Term, select
from segb_server.backend.store.terms import bind_rows
from segb_server.backend.vocabulary import KINDS, compact, kind_of

__all__ = ["MAX_NODES", "GraphRequest", "GraphService", "local_name", "parse_types"]

MAX_NODES = 20_000
INCOMING_LIMIT = 500  # statements pointing at one resource, read at once
READY_WAIT_SECONDS = 5.0  # how long a request waits for the index to be first built before a 503
# Journal entries on their way to the index that a summary reads and adds to it; past that, asking the store
# costs less than parsing them all.
PENDING_ENTRIES = 100
PARALLEL_QUERIES = 4  # a remote store's queries in flight at once for resource lookups (two per lookup)


class GraphService:
    def __init__(
        self,
        catalog: Catalog,
        store: Store,
        index: GraphIndex,
        wait_ready: Callable[[float], bool],
        pending: Callable[[int], list[Quad] | None] = lambda _limit: [],
    ) -> None:
        self.catalog = catalog
        self.store = store
        self.index = index
        self.wait_ready = wait_ready  # (timeout) -> whether the index answers (built, caught up at start)
        # (limit) -> the triples the store has and the views do not have yet, or None when they cannot stand in
        # for the store (a clearing among them, or more than `limit` entries)
        self.pending = pending
        # A remote store answers a resource's outgoing and incoming statements side by side (a round trip
        # saved per lookup); the embedded store's results must stay on the thread that made them.
        self._parallel = ThreadPoolExecutor(PARALLEL_QUERIES, "resource-queries") if store.remote else None

    def graph(self, request: GraphRequest) -> dict[str, object]:
        """The nodes and edges to draw; blocking (SQLite)."""
        if not self.index.ready and not self.wait_ready(READY_WAIT_SECONDS):
            raise ViewNotReady("The graph index is being built from the store; try again in a moment.")
        through = self.index.changed_through  # read first: a change made meanwhile is announced again, not lost
        return {**self.index.view(request), "through": through}

    def nodes(self, iris: Collection[str]) -> dict[str, dict[str, object]]:
        """These IRIs' nodes as `graph` draws them, by IRI: how a list names what it is about without drawing
        anything. An IRI the index holds no node of (not yet, or never) is left out; none while it is first built."""
        return self.index.nodes(iris) if self.index.ready else {}

    def resource(
        self, iri: str, *, incoming: Collection[str] | None = None, incoming_limit: int = INCOMING_LIMIT
    ) -> dict[str, object]:
        """Every triple from one resource and up to `incoming_limit` pointing at it (only those with the
        `incoming` predicates when given), with labels; blocking (store I/O). A robot after a month of logs is
        the object of hundreds of thousands of triples: `incoming_truncated` says when some were left out."""
        return self.resources([iri], incoming=incoming, incoming_limit=incoming_limit)[iri]

    def resources(
        self, iris: Sequence[str], *, incoming: Collection[str] | None = None, incoming_limit: int = INCOMING_LIMIT
    ) -> dict[str, dict[str, object]]:
        """`resource` of several IRIs with two queries for them all (a remote store costs a round trip per
        query, and an explanation reads a few dozen resources). Each still gets at most `incoming_limit`
        incoming statements; when the batch as a whole reaches its limit, which resource lost statements is
        unknown, so each is read again on its own."""
        iris = list(dict.fromkeys(iris))
        wrap = self.store.wraps_values
        parameter = PARAMETER_VARIABLE_PREFIX + "iri"
        out_text = bind_rows(self.catalog.get("graph/resource-out").text, [parameter],
                             [[NamedNode(iri)] for iri in iris], wrap=wrap)  # fmt: skip
        in_text = self.catalog.get("graph/resource-in").text
        if incoming is None:
            in_text = bind_rows(in_text, [parameter], [[NamedNode(iri)] for iri in iris], wrap=wrap)
        else:  # one VALUES row per (resource, predicate) instead of the resource alone
            rows: list[list[Term | None]] = [[NamedNode(i), NamedNode(p)] for i in iris for p in sorted(incoming)]
            in_text = bind_rows(in_text, [parameter, "predicate"], rows, wrap=wrap)
        limit = len(iris) * (incoming_limit + 1)
        out_rows, found = self._both(out_text, paged(in_text, limit, None))
        if len(iris) > 1 and len(found) >= limit:
            return {iri: self.resource(iri, incoming=incoming, incoming_limit=incoming_limit) for iri in iris}
        outgoing, pointing = self._by_resource(iris, out_rows), self._by_resource(iris, found)
        return {iri: _described(iri, outgoing[iri], pointing[iri], incoming_limit) for iri in iris}

    def close(self) -> None:
        if self._parallel is not None:
            self._parallel.shutdown(wait=False)
        self.index.close()

    def on_the_way(self) -> list[Quad] | None:
        """The triples the store has applied and the graph index not yet (a post just answered), read from the
        journal, for `summaries`; None when the store must answer instead: before the index is built, while a
        clearing is on its way to it, or more than `PENDING_ENTRIES` steps are. Read it before the index (as a
        reader calling `summaries` after it does): a step that reaches the index meanwhile is read twice, never
        missed."""
        return self.pending(PENDING_ENTRIES) if self.index.ready else None

    def summaries(
        self,
        iris: Sequence[str],
        pending: list[Quad] | None,
        *,
        incoming: Collection[str],
        incoming_limit: int = INCOMING_LIMIT,
    ) -> dict[str, dict[str, object]]:
        """`resources` for a reader that needs only links, types and the literals the graph index keeps whole
        (`GraphIndex.kept_literals`), without a store round trip: read from the index, with `pending` (what
        `on_the_way` read, once for all of a reader's calls) added; from the store when `pending` is None.
        Linked resources carry no labels here."""
        if pending is None:
            return self.resources(iris, incoming=incoming, incoming_limit=incoming_limit)
        iris = list(dict.fromkeys(iris))
        out_rows, in_rows = self.index.statements(iris, incoming, incoming_limit, pending)
        # By predicate, then value, as the store's query sorts them (values by their N-Triples text here: of
        # several numbers for one predicate, the first may differ from the store's numeric order).
        out_rows.sort(key=lambda row: (row["predicate"].value, str(row["value"])))
        outgoing, pointing = self._by_resource(iris, out_rows), self._by_resource(iris, in_rows)
        return {iri: _described(iri, outgoing[iri], pointing[iri], incoming_limit) for iri in iris}

    def _both(self, first: str, second: str) -> tuple[list[dict[str, Term]], list[dict[str, Term]]]:
        """The rows of two SELECT queries; at once on a remote store."""
        if self._parallel is None:
            return select(self.store, first).rows, select(self.store, second).rows
        later = self._parallel.submit(lambda: select(self.store, second).rows)
        return select(self.store, first).rows, later.result()

    def _by_resource(self, iris: list[str], rows: list[dict[str, Term]]) -> dict[str, list[dict[str, object]]]:
        grouped: dict[str, list[dict[str, Term]]] = {iri: [] for iri in iris}
        for row in rows:
            grouped[row["resource"].value].append(row)
        return {iri: self._statements_of(found) for iri, found in grouped.items()}

    def _statements_of(self, rows: list[dict[str, Term]]) -> list[dict[str, object]]:
        statements = []
        for row in rows:
            value = row["value"]
            statement: dict[str, object] = {
                "predicate": row["predicate"].value,
                "predicate_label": compact(row["predicate"].value),
                "value": json_value(value),
                "is_literal": isinstance(value, Literal),
            }
            if isinstance(value, Literal):
                statement["datatype"] = compact(value.datatype.value)
                if value.language:
                    statement["language"] = value.language
            elif "valueLabel" in row:
                statement["label"] = row["valueLabel"].value
            else:
                statement["label"] = local_name(value.value) if isinstance(value, NamedNode) else str(json_value(value))
            statements.append(statement)
        return statements


def _described(
    iri: str, outgoing: list[dict[str, object]], incoming: list[dict[str, object]], incoming_limit: int
) -> dict[str, object]:
    """A resource as `GraphService.resource` answers it, from its statements."""
    types = {str(s["value"]) for s in outgoing if s["predicate"] == RDF_TYPE}
    literals: dict[str, str] = {}
    for statement in outgoing:
        if statement["is_literal"]:
            literals.setdefault(str(statement["predicate"]), str(statement["value"]))
    kind = kind_of(types, timestamped=GENERATED_AT in literals)
    category = next((str(s["value"]) for s in outgoing if s["predicate"] == CATEGORY), None)
    node: dict[str, object] = {
        "id": iri,
        "label": display_label(iri, kind, literals, category),
        "kind": kind,
        "types": sorted(compact(t) for t in types),
    }
    time = own_time(literals)
    if time:
        node["time"] = time
    return {
        **node,
        "iri": iri,
        "outgoing": outgoing,
        "incoming": sorted(incoming[:incoming_limit], key=lambda s: (s["predicate"], str(s["value"]))),
        "incoming_truncated": len(incoming) > incoming_limit,
    }


def parse_types(raw: str | None) -> tuple[str, ...]:
    if not raw:
        return ()
    values = tuple(part.strip() for part in raw.split(",") if part.strip())
    for value in values:
        if value not in KINDS and ":" not in value:
            raise InvalidParameter("types", f"'{value}' is neither a kind ({', '.join(KINDS)}) nor a class IRI/CURIE")
    return values
