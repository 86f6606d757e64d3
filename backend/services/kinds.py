"""Which kind of thing a resource is, from its RDF types, as the UI groups and colours them.

The PyPI client types many things `prov:Activity` (models, annotations, states), so kinds are decided by
the specific classes it emits, in priority order (see the RDF shapes notes): a model is never an
activity, an emotion annotation is never a state.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Literal

from segb_server.backend.services.namespaces import PREFIXES

Kind = Literal["robot", "human", "message", "emotion", "model", "shared-event", "state", "activity", "other"]
KINDS: tuple[Kind, ...] = (
    "robot",
    "human",
    "shared-event",
    "activity",
    "message",
    "emotion",
    "state",
    "model",
    "other",
)


def _iri(curie: str) -> str:
    prefix, local = curie.split(":", 1)
    return PREFIXES[prefix] + local


_CLASSES: list[tuple[Kind, frozenset[str]]] = [
    ("robot", frozenset({_iri("oro:Robot")})),
    ("human", frozenset({_iri("oro:Human"), _iri("foaf:Person"), _iri("prov:Person")})),
    ("message", frozenset({_iri("schema:Message")})),
    ("emotion", frozenset({_iri("onyx:Emotion"), _iri("amor:EmotionAnnotation"), _iri("oa:Annotation")})),
    ("model", frozenset({_iri("mls:Model")})),
    ("shared-event", frozenset({_iri("schema:Event")})),
]
_ACTIVITY = frozenset({_iri("segb:LoggedActivity"), _iri("mls:Run")})
RESULT = _iri("segb:Result")


def kind_of(types: Collection[str], *, timestamped: bool = False) -> Kind:
    """The kind of a resource with these class IRIs. A state is a `segb:Result` with its own timestamp
    (`prov:generatedAtTime`): nothing else the client emits is both."""
    for kind, classes in _CLASSES:
        if not classes.isdisjoint(types):
            return kind
    if RESULT in types and timestamped:
        return "state"
    if not _ACTIVITY.isdisjoint(types):
        return "activity"
    return "other"
