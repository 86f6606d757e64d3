"""Telling the form of a SPARQL query (SELECT, CONSTRUCT, ASK, DESCRIBE) from its text."""

from __future__ import annotations

import re
from typing import Literal, cast

QueryForm = Literal["select", "construct", "ask", "describe"]

# The prologue: comments, BASE <iri> and PREFIX name: <iri> declarations, in any order.
_PROLOGUE = re.compile(
    r"(?:\s+|\#[^\n]*|BASE\s*<[^>]*>|PREFIX\s+[^\s:]*:\s*<[^>]*>)*",
    re.IGNORECASE,
)
_FORM = re.compile(r"(SELECT|CONSTRUCT|ASK|DESCRIBE)\b", re.IGNORECASE)
_SELECT_DISTINCT = re.compile(r"SELECT\s+DISTINCT\b", re.IGNORECASE)


def _after_prologue(sparql: str) -> int:
    found = _PROLOGUE.match(sparql)
    return found.end() if found else 0


def query_form(sparql: str) -> QueryForm | None:
    """The query's form, or None when the text does not start (after its prologue) with one.

    Remote stores pick a result format from the Accept header, so the form has to be known before sending.
    """
    form = _FORM.match(sparql, _after_prologue(sparql))
    return cast(QueryForm, form.group(1).lower()) if form else None


def is_distinct(sparql: str) -> bool:
    """Whether the query's own SELECT (after its prologue) is DISTINCT: a subquery's DISTINCT says nothing of the
    answer. Read from the head alone: the rest of a kept view's query is often a VALUES block of hundreds of keys,
    whose strings and IRIs, blanked on every answer, cost more than reading the answer."""
    return _SELECT_DISTINCT.match(sparql, _after_prologue(sparql)) is not None
