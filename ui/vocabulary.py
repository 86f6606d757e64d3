"""The namespaces and kinds the API knows (GET /vocabulary), fetched once and kept: they are fixed in the
server's code, so every page of every UI shows the same names as the API without importing the backend."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

from segb_server.ui.api_client import BackendClient, BackendError, BackendUnavailable


@dataclass(frozen=True)
class Vocabulary:
    prefixes: dict[str, str] = field(default_factory=dict)
    kinds: tuple[str, ...] = ()
    name_predicates: tuple[str, ...] = ()  # where a display name is read, best first (the server's rule of reading)
    human_classes: tuple[str, ...] = ()

    def compact(self, iri: str) -> str:
        """`prefix:local` when the IRI is in a known namespace, else the IRI itself."""
        return _compact(iri, tuple(self.prefixes.items()))


@lru_cache(maxsize=4096)  # the same few hundred predicates and classes come back on every page
def _compact(iri: str, prefixes: tuple[tuple[str, str], ...]) -> str:
    for name, namespace in prefixes:
        if iri.startswith(namespace) and len(iri) > len(namespace):
            return f"{name}:{iri[len(namespace) :]}"
    return iri


_known = Vocabulary()


def current() -> Vocabulary:
    """What is known so far: empty until the API first answered (pages then show plain local names)."""
    return _known


async def ensure(client: BackendClient) -> Vocabulary:
    """The vocabulary, asking the API the first time (and again while it has not answered)."""
    global _known
    if not _known.prefixes:
        try:
            body = await client.get_json("/vocabulary")
        except (BackendError, BackendUnavailable):
            return _known
        _known = Vocabulary(
            dict(body["prefixes"]),
            tuple(body["kinds"]),
            tuple(body.get("name_predicates", ())),
            tuple(body.get("human_classes", ())),
        )
    return _known
