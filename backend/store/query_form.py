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


def query_form(sparql: str) -> QueryForm | None:
    """The query's form, or None when the text does not start (after its prologue) with one.

    Remote stores pick a result format from the Accept header, so the form has to be known before sending.
    """
    prologue_end = _PROLOGUE.match(sparql)
    start = prologue_end.end() if prologue_end else 0
    form = _FORM.match(sparql, start)
    return cast(QueryForm, form.group(1).lower()) if form else None
