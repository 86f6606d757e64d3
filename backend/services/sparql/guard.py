"""Deciding whether a user's SPARQL may run: read queries over the events graph only, nothing that reaches
outside it (updates, federation, Virtuoso's SQL and file-system extensions, other graphs or datasets).

Every check works on rdflib's parse tree of the query, so comments, strings, Unicode escapes and odd spacing
cannot hide a keyword. The text handed to the store is the one that was parsed (escapes expanded), so what
was checked is exactly what runs.

Dataset policy: the events graph is the query's default graph and there are no named graphs. `FROM <events
graph>` is accepted and dropped (it changes nothing); `FROM` naming any other graph, `FROM NAMED` and `GRAPH`
patterns are rejected. On Virtuoso, GRAPH and FROM would otherwise reach every graph of the database.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import lru_cache

from pyparsing import ParseBaseException, ParseResults
from rdflib.plugins.sparql.parser import expandUnicodeEscapes
from rdflib.plugins.sparql.parserutils import CompValue
from rdflib.term import URIRef

from segb_server.backend.services.errors import InvalidQuery, PayloadTooLarge
from segb_server.backend.services.sparql.parser import parse_query, parse_update
from segb_server.backend.store.query_form import QueryForm, query_form
from segb_server.backend.store.sparql_text import code_only as _code_only

MAX_QUERY_BYTES = 100_000
# rdflib spends one to two milliseconds on each operator, comma, function call and group of a query (a tenth of
# that on triples and VALUES rows): more than this many would keep it parsing for seconds.
MAX_QUERY_TERMS = 2_000

# Reasons, in the order they are reported when a query has several problems (the most serious first).
REASONS = (
    "too_long",
    "too_complex",
    "empty",
    "multiple_queries",
    "virtuoso_pragma",
    "update",
    "syntax",
    "too_deep",
    "virtuoso_extension",
    "service",
    "extension_function",
    "dataset",
    "graph",
    "undeclared_prefix",
)

_FORMS: dict[str, QueryForm] = {
    "SelectQuery": "select",
    "ConstructQuery": "construct",
    "AskQuery": "ask",
    "DescribeQuery": "describe",
}
UPDATE_VERBS = frozenset({"INSERT", "DELETE", "LOAD", "CLEAR", "DROP", "CREATE", "COPY", "MOVE", "ADD", "WITH"})

# Virtuoso maps these to its SQL built-ins and stored procedures (file access, HTTP, system calls), and keeps
# its own internal vocabularies under openlinksw.com. Matched case-insensitively on the expanded IRI.
_VIRTUOSO_IRIS = ("bif:", "sql:", "http://www.openlinksw.com/")
_VIRTUOSO_PREFIXES = frozenset({"bif", "sql"})
# Functions called by IRI must be standard: XSD casts and the XPath function library.
_CALLABLE_NAMESPACES = (
    "http://www.w3.org/2001/XMLSchema#",
    "http://www.w3.org/2005/xpath-functions#",
    "http://www.w3.org/2005/xpath-functions/math#",
)

# Keywords are bare words: not part of a variable (?x, $x), prefixed name (ex:x, x:) or blank node (_:x).
_WORD_START = r"(?<![\w:?$.\-])"
_DEFINE = re.compile(_WORD_START + r"define\s+[A-Za-z_][\w.\-]*:", re.IGNORECASE)
_PROLOGUE = re.compile(r"(?:\s+|BASE\s*<[^>]*>|PREFIX\s+[^\s:]*:\s*<[^>]*>)*", re.IGNORECASE)
_FIRST_WORD = re.compile(r"[A-Za-z]+")
_FROM = re.compile(_WORD_START + r"FROM\s+(?:NAMED\s+)?(?:<[^>]*>|[^\s<{]*:[^\s{]*)", re.IGNORECASE)
# What costs rdflib's parser time: operators, commas, opening brackets (calls, FILTERs, groups). Counted in the
# code only, after the IRIs (`<` and `>` around blanks there) are dropped.
_EMPTIED_IRI = re.compile(r"<\s*>")
_COSTLY_TERM = re.compile(r"\|\||&&|[-({=<>!+*/,]")


@dataclass(frozen=True)
class CheckedQuery:
    """A query that may run: its form, and the text to send to the store."""

    form: QueryForm
    text: str


class QueryTooLong(PayloadTooLarge):
    """The query text is over MAX_QUERY_BYTES (answered with 413)."""


class QueryTooComplex(PayloadTooLarge):
    """The query has more than MAX_QUERY_TERMS operators, commas and brackets (answered with 413)."""


def guard_query(query: str, events_graph: str | None = None) -> CheckedQuery:
    """The query's form ("select", "ask", "construct" or "describe") and the text to run (FROM <events graph>
    dropped) when it may run; else raise InvalidQuery (or QueryTooLong, QueryTooComplex) with `reason`, `line`
    and `column` in its details. With `events_graph` None, any FROM clause is rejected."""
    refuse_unparsable(query)
    # Parsing a long query takes rdflib tens of milliseconds; clients repeat the same queries (report pages).
    return _guard_parsed(query, events_graph)


def refuse_unparsable(query: str) -> None:
    """The checks made before parsing, cheap whatever the text: raise QueryTooLong, QueryTooComplex or
    InvalidQuery ("empty") for a query too long or too complex to parse, or with nothing to parse."""
    size = len(query.encode("utf-8"))
    if size > MAX_QUERY_BYTES:
        raise QueryTooLong(
            f"The query is {size} bytes; the limit is {MAX_QUERY_BYTES}.",
            reason="too_long",
            line=None,
            column=None,
            query_kind="unknown",
        )
    if not query.strip():
        raise query_rejected("empty", "The query is empty.")
    terms = len(_COSTLY_TERM.findall(_EMPTIED_IRI.sub(" ", _code_only(query))))
    if terms > MAX_QUERY_TERMS:
        raise QueryTooComplex(
            f"The query has {terms} operators, commas and brackets; the limit is {MAX_QUERY_TERMS}. Split it, or "
            "give long lists of values in a VALUES block.",
            reason="too_complex",
            line=None,
            column=None,
            query_kind=query_form(query) or "unknown",
        )


@lru_cache(maxsize=128)
def _guard_parsed(query: str, events_graph: str | None) -> CheckedQuery:
    try:
        text = expandUnicodeEscapes(query)
    except ValueError as error:
        raise query_rejected("syntax", f"Invalid SPARQL syntax: {error}.") from None
    try:
        tree = parse_query(text)
    except ParseBaseException as error:
        raise _not_a_query(text, error) from None
    except RecursionError:
        raise query_rejected("too_deep", "The query nests brackets too deeply to be checked; simplify it.") from None
    form = _FORMS[tree[1].name]
    _check_tree(tree, events_graph, form)
    return CheckedQuery(form=form, text=_drop_from_clauses(text, tree, form))


def query_rejected(
    reason: str, message: str, line: int | None = None, column: int | None = None, query_kind: str = "unknown"
) -> InvalidQuery:
    """The error for a refused query. `reason` is one of REASONS; `query_kind` is the form, "update", or
    "unknown" (as the reference's /query/validate reports it)."""
    return InvalidQuery(message, reason=reason, line=line, column=column, query_kind=query_kind)


# --- queries rdflib cannot parse --------------------------------------------------------------------------


def _not_a_query(text: str, error: ParseBaseException) -> InvalidQuery:
    """Say why a text is not a query: one with nothing but comments and prefixes is empty, a Virtuoso pragma or
    an update gets its own message, the rest is a syntax error at the parser's position."""
    code = _code_only(text)
    prologue = _PROLOGUE.match(code)
    # Checked before updates: rdflib parses such a text as an update of no operations.
    if prologue is not None and prologue.end() == len(code):
        return query_rejected(
            "empty", "The query is empty: its text holds only comments or BASE and PREFIX declarations."
        )
    pragma = _DEFINE.search(code)
    if pragma:
        line, column = _position(text, pragma.start())
        return query_rejected(
            "virtuoso_pragma",
            f"Virtuoso DEFINE pragmas (line {line}, column {column}) are not allowed: 'define input:…', "
            "'define sql:…' and the like change the dataset or reach the database engine.",
            line,
            column,
        )
    verb = _update_verb(text, code)
    if verb:
        return query_rejected(
            "update",
            f"SPARQL Update ({verb}) is not allowed: this endpoint is read-only and runs only SELECT, ASK, "
            "CONSTRUCT and DESCRIBE queries.",
            query_kind="update",
        )
    found = error.found if error.found != "end of text" else "end of the query"
    return query_rejected(
        "syntax",
        f"Invalid SPARQL syntax at line {error.lineno}, column {error.col}: unexpected {found}.",
        error.lineno,
        error.col,
        query_form(text) or "unknown",
    )


def _update_verb(text: str, code: str) -> str | None:
    """The update operation the text starts with, if it is an update (even one rdflib cannot parse)."""
    prologue = _PROLOGUE.match(code)
    first = _FIRST_WORD.match(code, prologue.end() if prologue else 0)
    if first and first.group().upper() in UPDATE_VERBS:
        return first.group().upper()
    try:
        parse_update(text)
    except (ParseBaseException, RecursionError):
        return None
    return "update"


def _position(text: str, offset: int) -> tuple[int, int]:
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


# --- parsed queries -------------------------------------------------------------------------------------


def _nodes(tree: object) -> Iterator[object]:
    """Every node of an rdflib parse tree (CompValues, ParseResults, terms)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, CompValue):
            # dict.values, not CompValue's accessors, which resolve variables against an evaluation context.
            stack.extend(dict.values(node))
        elif isinstance(node, ParseResults | list | tuple):
            stack.extend(node)


def _check_tree(tree: ParseResults, events_graph: str | None, form: QueryForm) -> None:
    prefixes = {dict.get(decl, "prefix") or "": str(decl["iri"]) for decl in tree[0] if decl.name == "PrefixDecl"}
    problems: dict[str, str] = {}

    def note(reason: str, message: str) -> None:
        problems.setdefault(reason, message)

    def check_iri(iri: str) -> None:
        if iri.lower().startswith(_VIRTUOSO_IRIS):
            note("virtuoso_extension", _virtuoso_message(iri))

    def expand(term: object) -> str | None:
        """The IRI a term names (a pname expanded with the query's prefixes), or None if it cannot be."""
        if isinstance(term, URIRef):
            return str(term)
        if isinstance(term, CompValue) and term.name == "pname":
            prefix = dict.get(term, "prefix") or ""
            if prefix in prefixes:
                return prefixes[prefix] + (dict.get(term, "localname") or "")
        return None

    for node in _nodes(tree):
        if isinstance(node, URIRef):
            check_iri(str(node))
        elif not isinstance(node, CompValue):
            continue
        elif node.name == "pname":
            prefix = dict.get(node, "prefix") or ""
            if prefix in prefixes:
                check_iri(prefixes[prefix] + (dict.get(node, "localname") or ""))
            elif prefix.lower() in _VIRTUOSO_PREFIXES:
                note("virtuoso_extension", _virtuoso_message(f"{prefix}:{dict.get(node, 'localname') or ''}"))
            else:
                note("undeclared_prefix", f"The prefix '{prefix}:' is not declared; add 'PREFIX {prefix}: <…>'.")
        elif node.name == "ServiceGraphPattern":
            note(
                "service",
                "SERVICE clauses are not allowed: a federated query would make the server fetch other endpoints.",
            )
        elif node.name == "Function":
            iri = expand(dict.get(node, "iri"))
            if (
                iri is not None
                and not iri.lower().startswith(_VIRTUOSO_IRIS)
                and not iri.startswith(_CALLABLE_NAMESPACES)
            ):
                note(
                    "extension_function",
                    f"Calling <{iri}> is not allowed: only XSD casts and XPath functions can be called by IRI.",
                )
        elif node.name == "GraphGraphPattern":
            note(
                "graph",
                "GRAPH patterns are not supported: the events graph is the query's default graph and there are no "
                "named graphs; write the patterns without GRAPH.",
            )
        elif node.name == "DatasetClause":
            _check_dataset_clause(node, expand, events_graph, note)

    if problems:
        reason = min(problems, key=REASONS.index)
        raise query_rejected(reason, problems[reason], query_kind=form)


def _check_dataset_clause(
    clause: CompValue,
    expand: Callable[[object], str | None],
    events_graph: str | None,
    note: Callable[[str, str], None],
) -> None:
    if "named" in clause:
        note(
            "dataset",
            "FROM NAMED is not supported: the events graph is the query's default graph and there are no named graphs.",
        )
        return
    iri = expand(dict.get(clause, "default"))
    if events_graph is None or iri != events_graph:
        only = f" <{events_graph}>" if events_graph else ""
        note(
            "dataset",
            f"FROM <{iri}> is not allowed: every query runs over the events graph{only} as its default graph, and "
            "FROM can name only that graph.",
        )


def _virtuoso_message(name: str) -> str:
    return (
        f"Virtuoso extensions are not allowed (found '{name}'): 'bif:' and 'sql:' functions and OpenLink "
        "vocabularies reach the database engine and the server's file system."
    )


def _drop_from_clauses(text: str, tree: ParseResults, form: QueryForm) -> str:
    """The text with its `FROM <events graph>` clauses blanked out (only those remain after the checks).

    The embedded store would read `FROM <g>` as "the named graph g", which is empty there: the events are its
    default graph. Virtuoso would ignore it (the store sends the dataset as a protocol parameter)."""
    clauses = [node for node in _nodes(tree[1]) if isinstance(node, CompValue) and node.name == "DatasetClause"]
    if not clauses:
        return text
    found = list(_FROM.finditer(_code_only(text)))
    if len(found) != len(clauses):
        # The text and the parse tree disagree about where the clauses are: refuse rather than guess.
        raise query_rejected("dataset", "Could not locate the FROM clauses of the query; drop them.", query_kind=form)
    pieces = []
    last = 0
    for match in found:
        pieces += [text[last : match.start()], " " * (match.end() - match.start())]
        last = match.end()
    pieces.append(text[last:])
    return "".join(pieces)
