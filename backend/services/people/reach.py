"""What an erasure of one person reaches, and what it must never reach.

The rule (`sparql/people/erase.rq`) lists candidates, each with the resource it was reached from. A link alone
proves nothing: any robot may point its own resources at anyone's, so a candidate is kept only when it is not an
agent (a person, a robot), nor a class or a predicate (typed as one, or used as one in the store), and when what
it was reached from is kept too. Who is a person is `vocabulary.PERSON_CLASSES`, the one rule.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from pyoxigraph import Literal, NamedNode, Triple

from segb_server.backend.services.errors import InvalidParameter, NotFound
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.terms import bind_rows
from segb_server.backend.vocabulary import AGENT_CLASSES, PERSON_CLASSES, PREFIXES, ROBOT_CLASSES, compact, kind_of

RESOURCES_PER_QUERY = 200
# Types that make a resource someone (or something acting): an erasure of one person never takes another.
AGENTS = AGENT_CLASSES | {
    PREFIXES["prov"] + "Agent",
    PREFIXES["prov"] + "SoftwareAgent",
    PREFIXES["prov"] + "Organization",
    PREFIXES["foaf"] + "Agent",
    PREFIXES["foaf"] + "Organization",
    PREFIXES["schema"] + "Organization",
}
# Types that make a resource a term of a vocabulary, which every robot's log shares.
VOCABULARY_TERMS = frozenset(
    {
        PREFIXES["rdfs"] + "Class",
        PREFIXES["owl"] + "Class",
        PREFIXES["rdf"] + "Property",
        PREFIXES["owl"] + "ObjectProperty",
        PREFIXES["owl"] + "DatatypeProperty",
    }
)
# Kinds the vocabulary's `kind_of` leaves as "other", named for a preview.
_OTHER_KINDS = {
    PREFIXES["sosa"] + "Observation": "observation",
    PREFIXES["sosa"] + "Procedure": "procedure",
    PREFIXES["schema"] + "PropertyValue": "property",
    PREFIXES["prov"] + "Entity": "observation",
}
_STANDING = """PREFIX rdfs: <http://www.w3.org/2000/01/rdf-schema#>
SELECT ?resource ?type ?asClass ?asSuperclass ?asPredicate WHERE {
  OPTIONAL { ?resource a ?type }
  BIND (EXISTS { ?instance a ?resource } AS ?asClass)
  BIND (EXISTS { ?narrower rdfs:subClassOf ?resource } AS ?asSuperclass)
  BIND (EXISTS { ?subject ?resource ?object } AS ?asPredicate)
}"""  # one EXISTS a BIND: Virtuoso 7 refuses `EXISTS {…} || EXISTS {…}` (and answers 1 or 0 for true or false)
_HELD = "SELECT ?predicate WHERE { { ?resource ?predicate ?value } UNION { ?subject ?predicate ?resource } } LIMIT 1"
_ABOUT = """SELECT ?s ?p ?o WHERE {
  { ?r ?p ?o . BIND (?r AS ?s) } UNION { ?s ?p ?r . BIND (?r AS ?o) }
}"""


@dataclass(frozen=True)
class Standing:
    """What the store says a resource is: its types, and whether it is used as a class or a predicate."""

    types: frozenset[str]
    used_as_term: bool

    @property
    def barred(self) -> bool:
        """An agent or a vocabulary term: never erased with someone else."""
        return self.used_as_term or not self.types.isdisjoint(AGENTS | VOCABULARY_TERMS)


@dataclass(frozen=True)
class Reach:
    """The resources an erasure of a person takes (the person first), and how many the rule reached that it
    leaves out (an agent, a class, a predicate, or what was reached only through one)."""

    resources: list[str]
    left_out: int


def standing(store: Store, iris: Iterable[str]) -> dict[str, Standing]:
    """How the store types each IRI and whether it uses it as a class or a predicate."""
    types: dict[str, set[str]] = {}
    terms: set[str] = set()
    ordered = sorted(set(iris))
    for start in range(0, len(ordered), RESOURCES_PER_QUERY):
        chunk: list[list[NamedNode | None]] = [[NamedNode(iri)] for iri in ordered[start : start + RESOURCES_PER_QUERY]]
        # Opening the group, whatever the store (no FILTER here): each EXISTS then sees its row's resource, and
        # Virtuoso keeps the rows its OPTIONAL does not match (wrapped, it drops them).
        for row in select(store, bind_rows(_STANDING, ["resource"], chunk, wrap=False)).rows:  # type: ignore[arg-type]
            iri = row["resource"].value
            found = types.setdefault(iri, set())
            if isinstance(row.get("type"), NamedNode):
                found.add(row["type"].value)
            if any(_true(row.get(flag)) for flag in ("asClass", "asSuperclass", "asPredicate")):
                terms.add(iri)
    return {iri: Standing(frozenset(types.get(iri, ())), iri in terms) for iri in ordered}


def check_erasable(store: Store, human: str) -> None:
    """404 when the store holds nothing about `human`; 422 unless the log types them as a person, and only as
    one: an erasure cannot be undone, and an IRI no robot typed as someone may be anything (a class, a term)."""
    person = standing(store, [human])[human]
    if person.used_as_term:
        raise InvalidParameter("iri", f"is not a person: <{human}> is a class or a predicate the log uses")
    if not person.types:
        if not select(store, _HELD, {"resource": NamedNode(human)}).rows:
            raise NotFound(f"Nothing about <{human}> is held: nothing was erased.")
        classes = " or ".join(compact(iri) for iri in sorted(PERSON_CLASSES))
        raise InvalidParameter(
            "iri", f"is not a person: the log does not type <{human}> as {classes}; only a person is erased"
        )
    check_person_types(human, person.types)
    also = person.types & (ROBOT_CLASSES | VOCABULARY_TERMS)  # a person may be an agent too, never a robot or a term
    if also:
        kinds = ", ".join(sorted(compact(iri) for iri in also))
        raise InvalidParameter("iri", f"is not a person alone: the log also types <{human}> as {kinds}")


def check_person_types(human: str, types: Iterable[str]) -> None:
    """422 when the log types `human` and as something else than a person (a robot, a model, a message)."""
    typed = set(types)
    if typed and typed.isdisjoint(PERSON_CLASSES):
        named = ", ".join(f"<{iri}>" for iri in sorted(typed)[:3])
        raise InvalidParameter("iri", f"is not a person: the log types <{human}> as {named}")


def reach(store: Store, rule: CatalogQuery, human: str) -> Reach:
    """The rule's candidates for `human`, kept when neither barred nor reached only through one left out."""
    rows = select(store, rule.text, rule.bindings({"human": human})).rows
    sources: dict[str, set[str | None]] = {}
    for row in rows:
        resource, via = row.get("resource"), row.get("via")
        if isinstance(resource, NamedNode):
            sources.setdefault(resource.value, set()).add(via.value if isinstance(via, NamedNode) else None)
    barred = {iri for iri, found in standing(store, set(sources) - {human}).items() if found.barred}
    kept = {human} if human in sources else set()
    growing = True
    while growing:  # as deep as the rule's chains (person → event → observation → procedure): a few rounds
        reached = {iri for iri, vias in sources.items() if iri not in kept | barred and not vias.isdisjoint(kept)}
        kept |= reached
        growing = bool(reached)
    return Reach(sorted(kept, key=lambda iri: (iri != human, iri)), len(sources) - len(kept))


def kinds(store: Store, resources: list[str]) -> dict[str, int]:
    """How many of `resources` are of each kind (message, emotion, shared event, …), as a preview tells them."""
    counted: Counter[str] = Counter()
    for found in standing(store, resources).values():
        kind: str = kind_of(found.types)
        if kind == "other":
            kind = next((name for iri, name in _OTHER_KINDS.items() if iri in found.types), "other")
        counted[kind] += 1
    return dict(sorted(counted.items()))


def triples_about(store: Store, resources: list[str]) -> Iterator[Triple]:
    """Every triple of the store whose subject or object is one of `resources` (one with both, twice)."""
    for start in range(0, len(resources), RESOURCES_PER_QUERY):
        chunk = [[NamedNode(iri)] for iri in resources[start : start + RESOURCES_PER_QUERY]]
        bound = bind_rows(_ABOUT, ["r"], chunk, wrap=store.wraps_values)  # type: ignore[arg-type]
        for row in select(store, bound).rows:
            yield Triple(row["s"], row["p"], row["o"])  # type: ignore[arg-type]


def _true(term: object) -> bool:
    return isinstance(term, Literal) and term.value in ("true", "1")
