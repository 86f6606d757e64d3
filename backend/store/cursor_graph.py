"""A SPARQL store's cursor graph, as SPARQL text: how far the journal is applied, and by which apply epoch.

A graph of its own beside the events graph (queries never see it) holds the cursor, `<urn:segb:journal>
<urn:segb:appliedThrough> N`, and where hosts share the store (a PostgreSQL state), the newest apply epoch that
wrote the store, `<urn:segb:journal> <urn:segb:appliedByEpoch> E`. A cursor written with an epoch is one update
whose WHERE holds only while the store has seen no newer epoch: the store decides, in the request that moves the
cursor, whether its writer still leads.
"""

from __future__ import annotations

from pyoxigraph import QuerySolutions

from segb_server.backend.store.base import CURSOR_PREDICATE, CURSOR_SUBJECT, EPOCH_PREDICATE


class CursorGraph:
    def __init__(self, events_graph: str) -> None:
        self.iri = f"urn:segb:applied:{events_graph}"

    def cursors(self) -> str:
        return f"SELECT ?n WHERE {{ GRAPH <{self.iri}> {{ {CURSOR_SUBJECT} {CURSOR_PREDICATE} ?n }} }}"

    def newest_epoch(self) -> str:
        return f"SELECT (MAX(?e) AS ?newest) WHERE {{ GRAPH <{self.iri}> {{ {CURSOR_SUBJECT} {EPOCH_PREDICATE} ?e }} }}"

    def held(self) -> str:
        """The cursors and the epochs, as `?p ?o` (read by `refusal`)."""
        return f"SELECT ?p ?o WHERE {{ GRAPH <{self.iri}> {{ {CURSOR_SUBJECT} ?p ?o }} }}"

    def record(self, through: int, epoch: int | None) -> str:
        """The cursor at `through` alone in the graph; with `epoch`, the epoch beside it, unless a newer one wrote."""
        graph = f"<{self.iri}>"
        if epoch is None:
            return (
                f"DELETE WHERE {{ GRAPH {graph} {{ ?s ?p ?o }} }} ;\n"
                f"INSERT DATA {{ GRAPH {graph} {{ {CURSOR_SUBJECT} {CURSOR_PREDICATE} {through} }} }}"
            )
        unfenced = self._unfenced(epoch)
        return (
            f"DELETE {{ GRAPH {graph} {{ ?s ?p ?o }} }} WHERE {{ GRAPH {graph} {{ ?s ?p ?o }} {unfenced} }} ;\n"
            f"INSERT {{ GRAPH {graph} {{ {CURSOR_SUBJECT} {CURSOR_PREDICATE} {through} . "
            f"{CURSOR_SUBJECT} {EPOCH_PREDICATE} {epoch} }} }} WHERE {{ {unfenced} }}"
        )

    def claim(self, epoch: int) -> str:
        """`epoch` added, unless a newer one wrote. The older epochs stay until this one's first cursor: a writer of
        one then reads back whether its last cursor was in before the claim (`refusal`)."""
        return (
            f"INSERT {{ GRAPH <{self.iri}> {{ {CURSOR_SUBJECT} {EPOCH_PREDICATE} {epoch} }} }} "
            f"WHERE {{ {self._unfenced(epoch)} }}"
        )

    def _unfenced(self, epoch: int) -> str:
        """A WHERE group with one solution while the store has seen no apply epoch newer than `epoch`, none after.
        Counted in a subquery: Virtuoso 7 answers a group of FILTER NOT EXISTS alone, or of an OPTIONAL and a
        FILTER on it, wrongly (the first always true, the second never)."""
        return (
            f"{{ SELECT (COUNT(*) AS ?newer) WHERE {{ GRAPH <{self.iri}> {{ {CURSOR_SUBJECT} {EPOCH_PREDICATE} ?epoch "
            f"FILTER (?epoch > {epoch}) }} }} }} FILTER (?newer = 0)"
        )


def newest(solutions: QuerySolutions) -> int | None:
    """The answer to `CursorGraph.newest_epoch`."""
    found = next((row["newest"] for row in solutions if row["newest"] is not None), None)
    return None if found is None else int(found.value)


def refusal(held: QuerySolutions, through: int, epoch: int) -> int | None:
    """After a cursor written at `through` with `epoch`, from the answer to `CursorGraph.held`: the newer epoch that
    refused it, or None when it took effect (the cursor and this epoch there: it was in before any newer claim)."""
    values = [(row["p"], int(row["o"].value)) for row in held]
    cursors = {value for predicate, value in values if predicate == CURSOR_PREDICATE}
    epochs = {value for predicate, value in values if predicate == EPOCH_PREDICATE}
    newer = max(epochs, default=epoch)
    return newer if newer > epoch and not (through in cursors and epoch in epochs) else None
