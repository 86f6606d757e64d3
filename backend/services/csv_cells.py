"""Cells of the CSV downloads (reports, timeline, findings, /sparql's CSV and TSV answers), safe to open in a
spreadsheet.

Robots' text ends up in these cells, and a spreadsheet runs a cell that starts with `=`, `+`, `-` or `@` (or a tab
or carriage return before one) as a formula: `=HYPERLINK("http://evil/", "click")` in what a visitor said would
become a live link in the auditor's sheet (OWASP's "CSV injection"). Such a cell is written with a leading
apostrophe, which spreadsheets take as "this is text". A number keeps its sign (an emotion's negative valence
stays a number), and the JSON and XML answers are never changed: only what spreadsheets open.

/sparql's TSV answer writes each value as an RDF term (`"text"@en`, `<iri>`, a bare number); a spreadsheet drops
a literal's quotes, so the rule applies to the literal's text inside them.
"""

from __future__ import annotations

import csv
import io
import re

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
# A TSV term that is a literal: its quoted text (N-Triples escapes inside), then any language tag or datatype.
_TSV_LITERAL = re.compile(r'"((?:[^"\\]|\\.)*)"(.*)', re.DOTALL)


def spreadsheet_safe(text: str) -> str:
    """`text` as a CSV cell: prefixed with an apostrophe when a spreadsheet would read it as a formula."""
    if text.startswith(FORMULA_STARTS) and not _NUMBER.fullmatch(text):
        return "'" + text
    return text


def spreadsheet_safe_answer(body: bytes, media_type: str) -> bytes:
    """A SPARQL answer written in `media_type`, its cells spreadsheet_safe when that is CSV or TSV."""
    if media_type == "text/csv":
        return _safe_csv(body.decode("utf-8")).encode("utf-8")
    if media_type == "text/tab-separated-values":
        return _safe_tsv(body.decode("utf-8")).encode("utf-8")
    return body


def _safe_csv(text: str) -> str:
    written = io.StringIO()
    writer = csv.writer(written, lineterminator="\r\n")  # SPARQL's CSV ends its lines with CRLF
    writer.writerows([spreadsheet_safe(cell) for cell in row] for row in csv.reader(io.StringIO(text, newline="")))
    return written.getvalue()


def _safe_tsv(text: str) -> str:
    # A term holds no tab or line end of its own (they are escaped in it), so lines and tabs split it exactly.
    return "\n".join("\t".join(_safe_term(term) for term in line.split("\t")) for line in text.split("\n"))


def _safe_term(term: str) -> str:
    literal = _TSV_LITERAL.fullmatch(term)
    if literal is None:  # an IRI, a blank node, a bare number or boolean: no spreadsheet formula
        return term
    return f'"{spreadsheet_safe(literal[1])}"{literal[2]}'
