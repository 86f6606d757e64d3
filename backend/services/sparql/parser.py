"""rdflib's SPARQL parser, one call at a time.

rdflib parses SPARQL with pyparsing, whose grammar objects are shared, mutable module state: two threads
parsing at once corrupt it (a parse action is called with the wrong arguments) and every later parse in the
process fails too. Every use of the parser goes through this module, under one lock; the first parse runs at
import, while only one thread exists, so pyparsing settles its internal state before any concurrent use.
"""

from __future__ import annotations

import threading
from functools import lru_cache

from pyparsing import ParseResults
from rdflib.plugins.sparql.algebra import translateQuery
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


def parse_update(text: str) -> CompValue:
    """rdflib's parse tree of a SPARQL update (raises pyparsing's ParseBaseException, or RecursionError)."""
    with _lock:
        return parseUpdate(text)


parse_query("PREFIX warm: <urn:x:> SELECT ?s WHERE { ?s warm:p <urn:x:o> FILTER (?s != <urn:x:s>) } LIMIT 1")
