"""Namespaces of the vocabularies robots log with (see the RDF shapes the PyPI client emits)."""

from __future__ import annotations

from functools import lru_cache

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
