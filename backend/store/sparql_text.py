"""Reading SPARQL text without parsing it: where strings, IRIs and comments are, and where the query's own
WHERE group opens (for binding values into it)."""

from __future__ import annotations

import re
from functools import lru_cache

from segb_server.backend.store.query_form import query_form

# Strings, IRIs and comments, found left to right so a `#` inside a string is not taken for a comment.
_LEXEMES = re.compile(
    r'"""(?:[^"\\]|\\.|"(?!""))*"""'
    r"|'''(?:[^'\\]|\\.|'(?!''))*'''"
    r'|"(?:[^"\\\n\r]|\\.)*"'
    r"|'(?:[^'\\\n\r]|\\.)*'"
    r"|<[^<>\"{}|^`\\\x00-\x20]*>"
    r"|#[^\n\r]*",
    re.DOTALL,
)
_WHERE_BEFORE = re.compile(r"\bWHERE\s*$", re.IGNORECASE)


def code_only(text: str) -> str:
    """The text with strings and comments blanked and IRIs emptied (same length and line breaks), so keyword
    and bracket searches cannot match inside them."""

    def blank(match: re.Match[str]) -> str:
        lexeme = match.group()
        if lexeme.startswith("<"):
            return "<" + " " * (len(lexeme) - 2) + ">"
        return re.sub(r"[^\n]", " ", lexeme)

    return _LEXEMES.sub(blank, text)


@lru_cache(maxsize=32)  # the catalog's texts, bound to new values again and again; few, so little memory
def top_level_where(sparql: str) -> int | None:
    """The offset just after the `{` that opens the query's own WHERE group, or None if there is none.

    That group is the first top-level `{`, except in a CONSTRUCT, whose template comes first unless the
    short form `CONSTRUCT WHERE { … }` is used. Groups of subqueries are nested, so never top-level."""
    code = code_only(sparql)
    construct = query_form(sparql) == "construct"
    depth = 0
    for offset, character in enumerate(code):
        if character == "{":
            if depth == 0 and (not construct or _WHERE_BEFORE.search(code, 0, offset)):
                return offset + 1
            depth += 1
        elif character == "}":
            depth -= 1
    return None


def top_level_where_end(sparql: str) -> int | None:
    """The offset of the `}` that closes the query's own WHERE group, or None if there is none."""
    opening = top_level_where(sparql)
    if opening is None:
        return None
    code = code_only(sparql)
    depth = 1
    for offset in range(opening, len(code)):
        if code[offset] == "{":
            depth += 1
        elif code[offset] == "}":
            depth -= 1
            if depth == 0:
                return offset
    return None
