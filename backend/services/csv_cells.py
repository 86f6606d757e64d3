"""Cells of the CSV downloads (reports, timeline, findings), safe to open in a spreadsheet.

Robots' text ends up in these cells, and a spreadsheet runs a cell that starts with `=`, `+`, `-` or `@` (or a tab
or carriage return before one) as a formula: `=HYPERLINK("http://evil/", "click")` in what a visitor said would
become a live link in the auditor's sheet (OWASP's "CSV injection"). Such a cell is written with a leading
apostrophe, which spreadsheets take as "this is text". A number keeps its sign (an emotion's negative valence
stays a number), and the JSON answers are never changed: only what is meant for spreadsheets.
"""

from __future__ import annotations

import re

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def spreadsheet_safe(text: str) -> str:
    """`text` as a CSV cell: prefixed with an apostrophe when a spreadsheet would read it as a formula."""
    if text.startswith(FORMULA_STARTS) and not _NUMBER.fullmatch(text):
        return "'" + text
    return text
