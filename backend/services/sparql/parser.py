"""rdflib's SPARQL parser, one call at a time.

rdflib parses SPARQL with pyparsing, whose grammar objects are shared, mutable module state: two threads
parsing at once corrupt it (a parse action is called with the wrong arguments) and every later parse in the
process fails too. Every use of the parser goes through this module, under one lock; the first parse runs at
import, while only one thread exists, so pyparsing settles its internal state before any concurrent use.

The lock is for the server's own queries (the catalog's, read at start and planned once): users' queries are
checked in a process of their own (checkers.py), since one slow parse would hold every other parse behind it.
"""

from __future__ import annotations

import threading
from functools import lru_cache, partial

from pyparsing import ParseResults
from rdflib.plugins.sparql.algebra import translatePath, translatePName, translatePrologue, translateQuery, traverse
from rdflib.plugins.sparql.parser import parseQuery, parseUpdate
from rdflib.plugins.sparql.parserutils import CompValue

_lock = threading.Lock()


def parse_query(text: str) -> ParseResults:
    """rdflib's parse tree of a SPARQL query (raises pyparsing's ParseBaseException, or RecursionError)."""
    with _lock:
        return parseQuery(text)


@lru_cache(maxsize=64)
def translate_query(text: str) -> CompValue:
    """rdflib's algebra of a SPARQL query (raises on syntax errors). Kept per text: every app built in a process
    (a test's, a command's) plans the same report queries, a third of a second of parsing each. Shared, so
    callers read it and never change it."""
    with _lock:
        return translateQuery(parseQuery(text)).algebra


def exists_groups(text: str) -> list[CompValue]:
    """Every EXISTS and NOT EXISTS group of a query as written, names and property paths resolved but the groups
    not translated to algebra: rdflib's translation drops a FILTER nested in the group of an EXISTS that a BIND
    holds (`BIND (EXISTS { ?m :p ?h FILTER EXISTS { ?h a :C } } AS ?x)` keeps only `?m :p ?h`). Kept per text as
    `translate_query` is; the groups are shared, so callers read them and never change them."""
    return list(_exists_groups(text))


@lru_cache(maxsize=64)
def _exists_groups(text: str) -> tuple[CompValue, ...]:
    with _lock:
        parsed = parseQuery(text)
        prologue = translatePrologue(parsed[0], None)
        tree = traverse(parsed[1], visitPost=partial(translatePName, prologue=prologue))
        tree = traverse(tree, visitPost=translatePath)
    found: list[CompValue] = []

    def collect(node: object) -> None:
        if isinstance(node, CompValue):
            if node.name in ("Builtin_EXISTS", "Builtin_NOTEXISTS"):
                found.append(node["graph"])
            for key, value in node.items():
                if key != "_vars":
                    collect(value)
        elif isinstance(node, list | ParseResults):
            for item in node:
                collect(item)

    collect(tree)
    return tuple(found)


def parse_update(text: str) -> CompValue:
    """rdflib's parse tree of a SPARQL update (raises pyparsing's ParseBaseException, or RecursionError)."""
    with _lock:
        return parseUpdate(text)


def exclusive() -> threading.Lock:
    """The parser's lock, for code that parses through rdflib on its own (pySHACL): `with exclusive(): …`."""
    return _lock


parse_query("PREFIX warm: <urn:x:> SELECT ?s WHERE { ?s warm:p <urn:x:o> FILTER (?s != <urn:x:s>) } LIMIT 1")
