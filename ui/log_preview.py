"""What a log would add before it is published: its triples, its subjects, and which of them the graph does
not hold yet (asked of the API's read-only SPARQL endpoint in one query)."""

from __future__ import annotations

from dataclasses import dataclass, field

import anyio
from pyoxigraph import BlankNode, Literal, NamedNode, RdfFormat, parse

from segb_server.ui import vocabulary
from segb_server.ui.api_client import BackendClient
from segb_server.ui.display import short_iri

RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
# Without a name (as the server's rule of reading gives it, GET /vocabulary), a subject is shown by its text.
TEXT = "http://schema.org/text"
CHECKED_SUBJECTS = 500  # one query of this many IRIs; a longer log shows the count of the first ones
SHOWN_SUBJECTS = 50


@dataclass
class Subject:
    iri: str
    name: str | None = None
    types: list[str] = field(default_factory=list)
    rank: int = 1 << 30  # the name's predicate's place among the name predicates (lower is better)


@dataclass
class Preview:
    triples: int
    subjects: list[Subject]  # named subjects, in document order
    blank_subjects: int
    new: list[Subject] = field(default_factory=list)  # of the checked subjects, those the graph lacks

    @property
    def checked(self) -> int:
        return min(len(self.subjects), CHECKED_SUBJECTS)

    @property
    def shown_new(self) -> list[Subject]:
        return self.new[:SHOWN_SUBJECTS]


def read_log(text: str, name_predicates: tuple[str, ...] = ()) -> Preview | None:
    """The document's subjects (None when it does not parse: the API's validation says why), each named by the
    first of `name_predicates` it has, else by its text."""
    ranks = {predicate: rank for rank, predicate in enumerate((*name_predicates, TEXT))}
    subjects: dict[str, Subject] = {}
    blanks: set[str] = set()
    triples = 0
    try:
        for quad in parse(text.encode("utf-8"), RdfFormat.TURTLE):
            triples += 1
            subject, predicate, value = quad.subject, quad.predicate.value, quad.object
            if isinstance(subject, BlankNode):
                blanks.add(subject.value)
                continue
            if not isinstance(subject, NamedNode):
                continue
            known = subjects.setdefault(subject.value, Subject(subject.value))
            if predicate == RDF_TYPE and isinstance(value, NamedNode):
                known.types.append(short_iri(value.value))
            elif predicate in ranks and isinstance(value, Literal) and ranks[predicate] < known.rank:
                known.name, known.rank = value.value, ranks[predicate]
    except (SyntaxError, ValueError):
        return None
    return Preview(triples=triples, subjects=list(subjects.values()), blank_subjects=len(blanks))


async def preview(client: BackendClient, token: str | None, text: str) -> Preview | None:
    # Parsing a long log is CPU work: keep it off the event loop.
    names = (await vocabulary.ensure(client)).name_predicates
    found = await anyio.to_thread.run_sync(read_log, text, names)
    if found is None or not found.subjects:
        return found
    checked = found.subjects[:CHECKED_SUBJECTS]
    values = " ".join(str(NamedNode(subject.iri)) for subject in checked)
    query = f"SELECT ?s WHERE {{ VALUES ?s {{ {values} }} FILTER EXISTS {{ ?s ?p ?o }} }}"
    answer = (await client.sparql(query, "json", token=token)).json()
    present = {binding["s"]["value"] for binding in answer["results"]["bindings"]}
    found.new = [subject for subject in checked if subject.iri not in present]
    return found
