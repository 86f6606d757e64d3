"""Giving a person their data (GDPR Art. 15): every triple the store holds about them — exactly what erasing them
would remove — and the story of it in time order, for them to read (what they said, who replied, which emotions
were read on them with which model, when they were seen)."""

from __future__ import annotations

from dataclasses import dataclass

from pyoxigraph import Literal, Triple

from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.people.erasure import FIRST_NAME, ErasureService
from segb_server.backend.services.people.reach import triples_about
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.store.base import Store, select

STORY = "people/story"


@dataclass(frozen=True)
class PersonData:
    human: str
    name: str | None
    triples: list[Triple]
    story: list[dict[str, JsonValue]]


class PersonExport:
    def __init__(self, store: Store, erasure: ErasureService, story: CatalogQuery) -> None:
        self.store = store
        self.erasure = erasure
        self.story_query = story

    def export(self, human: str) -> PersonData:
        """Everything held about `human` (blocking); 404 when the store holds nothing about them, 422 when the log
        says it is not a person."""
        self.erasure.check_person(human)
        triples = sorted(set(triples_about(self.store, self.erasure.resources(human))), key=str)
        if not triples:
            raise NotFound(f"The store holds nothing about <{human}>.")
        rows = select(self.store, self.story_query.text, self.story_query.bindings({"human": human})).rows
        story = [{name: json_value(value) for name, value in row.items()} for row in rows]
        names = [
            t.object.value
            for t in triples
            if isinstance(t.object, Literal) and str(t.subject) == f"<{human}>" and t.predicate.value == FIRST_NAME
        ]
        return PersonData(human, names[0] if names else None, triples, story)
