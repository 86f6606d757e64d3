"""The vocabulary robots log with, shared by the API and (served at /vocabulary) the UI: namespaces, prefixes,
and the kinds of things the reports and the graph tell apart. No dependencies, so every layer may import it.

A kind is decided from a resource's RDF types. The PyPI client types many things `prov:Activity` (models,
annotations, states), so kinds follow the specific classes it emits, in priority order (see the RDF shapes
notes): a model is never an activity, an emotion annotation is never a state.
"""

from __future__ import annotations

from collections.abc import Collection
from functools import lru_cache
from typing import Literal

PREFIXES: dict[str, str] = {
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "xsd": "http://www.w3.org/2001/XMLSchema#",
    "owl": "http://www.w3.org/2002/07/owl#",
    "prov": "http://www.w3.org/ns/prov#",
    "foaf": "http://xmlns.com/foaf/0.1/",
    "schema": "http://schema.org/",
    "sosa": "http://www.w3.org/ns/sosa/",
    "oa": "http://www.w3.org/ns/oa#",
    "segb": "http://www.gsi.upm.es/ontologies/segb/ns#",
    "amor": "http://www.gsi.upm.es/ontologies/amor/ns#",
    "mls": "http://www.w3.org/ns/mls#",
    "oro": "http://kb.openrobots.org#",
    "onyx": "http://www.gsi.upm.es/ontologies/onyx/ns#",
    "emoml": "http://www.gsi.upm.es/ontologies/onyx/vocabularies/emotionml/ns#",
}

# The one statement that credits an act to a robot: the graph's lanes and the explanations both read it from here.
PERFORMED_BY = PREFIXES["segb"] + "wasPerformedBy"
# The statements whose object is credited with what their subject is: an act, words said, a state, a result. A
# token's write scopes hold for their objects as for subjects: its robot may not credit another with anything.
CREDITING = frozenset(
    {
        PERFORMED_BY,
        PREFIXES["schema"] + "sender",
        PREFIXES["prov"] + "wasAttributedTo",
        PREFIXES["prov"] + "wasAssociatedWith",
    }
)


def sparql_prologue() -> str:
    """PREFIX lines for every known namespace, e.g. to prefill a query editor."""
    return "".join(f"PREFIX {name}: <{iri}>\n" for name, iri in PREFIXES.items())


@lru_cache(maxsize=4096)  # the same few hundred predicates and classes come back in every graph
def compact(iri: str) -> str:
    """`prefix:local` when the IRI is in a known namespace, else the IRI itself."""
    for name, namespace in PREFIXES.items():
        if iri.startswith(namespace) and len(iri) > len(namespace):
            return f"{name}:{iri[len(namespace) :]}"
    return iri


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


# What is a human and what is a robot: the one rule every page, report, audit rule and erasure reads (the SPARQL
# of `%human(?x)` and `%robot(?x)` in backend/reading.py is made from these). An agent is either.
PERSON_CLASSES = frozenset({_iri("oro:Human"), _iri("foaf:Person"), _iri("prov:Person")})
ROBOT_CLASSES = frozenset({_iri("oro:Robot")})
AGENT_CLASSES = PERSON_CLASSES | ROBOT_CLASSES
_CLASSES: list[tuple[Kind, frozenset[str]]] = [
    ("robot", ROBOT_CLASSES),
    ("human", PERSON_CLASSES),
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
