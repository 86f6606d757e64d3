"""A person's names in the texts an erasure of them keeps: found, and replaced by a fixed mark.

Their names are what the log states for them: the display name's predicates (`reading.NAME_PREDICATES`) and the
full and given names (`NAME_STATEMENTS`). A text holds a name when the name is there as whole words, in any case
(Lucía, LUCÍA; not Luciano), compared in Unicode's composed form. Which texts are looked at is the rule
`sparql/people/mentions.rq` (what concerns the person by the rules of reading), or, asked for, every literal of the
store. Each found text is replaced where the journal holds it: its line leaves the post (and, withheld, is not
recorded again when a robot re-sends it) and the line with the names replaced stands in its place
(writing/erasure.py, `LineSelection.replace`).
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal as TypingLiteral

from pyoxigraph import Literal, NamedNode, RdfFormat, Triple, parse

from segb_server.backend.reading import NAME_PREDICATES
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.writing.erasure import LineSelection
from segb_server.backend.store.base import Store, select
from segb_server.backend.vocabulary import PREFIXES

RULE = "people/mentions"
MARK = "[erased]"
Scope = TypingLiteral["concerning", "store"]
# Besides the display name's: the full and given names a log may state for someone.
NAME_STATEMENTS = (PREFIXES["foaf"] + "name", PREFIXES["foaf"] + "givenName", PREFIXES["schema"] + "givenName")
_NAMES = "SELECT DISTINCT ?name WHERE { ?human ?predicate ?name FILTER (isLiteral(?name)) }"


class Names:
    """A person's names as one pattern: each as whole words, any case, the longest first (a full name is
    replaced whole before its first name is)."""

    def __init__(self, names: Iterable[str]) -> None:
        # One letter is no name to look for in text: it would take every such letter of their conversations.
        self.names = frozenset(_composed(name) for name in names if len(name.strip()) > 1)
        ordered = sorted(self.names, key=lambda name: (-len(name), name))
        alternatives = "|".join(r"\s+".join(map(re.escape, name.split())) for name in ordered)
        self._pattern = re.compile(rf"(?<!\w)(?:{alternatives})(?!\w)", re.IGNORECASE)

    def __bool__(self) -> bool:
        return bool(self.names)

    def found_in(self, text: str) -> bool:
        return bool(self.names) and self._pattern.search(_composed(text)) is not None

    def redacted(self, text: str) -> str:
        """The text with each of the names replaced by the mark; the rest as it was."""
        return self._pattern.sub(MARK, _composed(text)) if self.names else text


@dataclass(frozen=True)
class Mentions:
    """The texts of the store that hold one of a person's names and are to be redacted."""

    names: Names
    triples: frozenset[Triple]

    def __len__(self) -> int:
        return len(self.triples)

    def selection(self) -> LineSelection:
        """The journal's lines of these texts (as received, whatever their spelling), each replaced by the line
        with the names redacted."""
        places = {f"{triple.subject} {triple.predicate} ".encode() for triple in self.triples}

        def mentioned(line: bytes) -> Triple | None:
            subject, _, rest = line.partition(b" ")
            predicate, _, _ = rest.partition(b" ")
            if subject + b" " + predicate + b" " not in places:
                return None
            triple = _triple(line)
            if triple is None or not isinstance(triple.object, Literal) or not self.names.found_in(triple.object.value):
                return None
            return triple

        def replace(line: bytes) -> bytes | None:
            triple = mentioned(line)
            return None if triple is None else f"{redacted(triple, self.names)} .".encode()

        return LineSelection(lambda _recorded_at: True, lambda line: mentioned(line) is not None, replace)


def names_of(store: Store, human: str) -> Names:
    """The names the log states for `human` (read before they are erased)."""
    found: set[str] = set()
    for predicate in (*NAME_PREDICATES, *NAME_STATEMENTS):
        rows = select(store, _NAMES, {"human": NamedNode(human), "predicate": NamedNode(predicate)}).rows
        found |= {row["name"].value.strip() for row in rows if row["name"].value.strip()}
    return Names(found)


def mentions(store: Store, rule: CatalogQuery, human: str, names: Names, scope: Scope) -> Mentions:
    """The texts holding one of `names` that an erasure of `human` redacts: those the rule says concern them,
    or (`store`) every literal of the store but their own resources' (which go whole)."""
    if not names:
        return Mentions(names, frozenset())
    if scope == "store":
        rows = select(store, _everywhere(names)).rows
    else:
        rows = select(store, rule.text, rule.bindings({"human": human})).rows
    found = {
        Triple(row["subject"], row["predicate"], row["text"])  # type: ignore[arg-type]
        for row in rows
        if isinstance(row.get("subject"), NamedNode)
        and isinstance(row.get("text"), Literal)
        and row["subject"].value != human
        and names.found_in(row["text"].value)
    }
    return Mentions(names, frozenset(found))


def still_mentioned(store: Store, names: Names) -> int:
    """How many literals of the store still hold one of `names`."""
    if not names:
        return 0
    return sum(1 for row in select(store, _everywhere(names)).rows if names.found_in(row["text"].value))


def redacted(triple: Triple, names: Names) -> Triple:
    text = triple.object
    assert isinstance(text, Literal)
    replaced = names.redacted(text.value)
    literal = Literal(replaced, language=text.language) if text.language else Literal(replaced, datatype=text.datatype)
    return Triple(triple.subject, triple.predicate, literal)


def _everywhere(names: Names) -> str:
    """Every literal that may hold one of `names`: a first sieve the store runs (lower case, composed or not), the
    whole-word test in Python. The constants as plain literals: Virtuoso reads a non-ASCII one inside STR(…) as
    something else, and finds nothing."""
    forms = sorted({unicodedata.normalize(form, name).lower() for name in names.names for form in ("NFC", "NFD")})
    tests = " || ".join(f"CONTAINS(LCASE(STR(?text)), {Literal(form)})" for form in forms)
    return (
        f"SELECT ?subject ?predicate ?text WHERE {{ ?subject ?predicate ?text FILTER (isLiteral(?text) && ({tests})) }}"
    )


def _composed(text: str) -> str:
    return unicodedata.normalize("NFC", text)


def _triple(line: bytes) -> Triple | None:
    for quad in parse(line + b"\n", RdfFormat.N_TRIPLES):
        return quad.triple
    return None
