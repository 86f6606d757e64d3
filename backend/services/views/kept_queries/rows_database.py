"""The tables of the kept rows' database beside each report's own: the reports' state, the change log live
readers follow, the table of terms rows refer to by number, the rows' dictionaries and their keys' namespaces."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from segb_server.backend.services.views import terms
from segb_server.backend.services.views.kept_queries import key_namespaces, row_codec
from segb_server.backend.services.views.kept_queries.key_namespaces import KEY_NAMESPACES
from segb_server.backend.services.views.kept_queries.row_codec import DICTIONARIES

TERMS = "report_term_numbers"  # units and the IRIs filters compare, as numbers (views/terms.py, by digest)
SCHEMA = [
    "CREATE TABLE IF NOT EXISTS report_state (report TEXT PRIMARY KEY, fingerprint TEXT, through INTEGER)",
    "CREATE TABLE IF NOT EXISTS report_changes (seq INTEGER PRIMARY KEY AUTOINCREMENT, report TEXT, "
    "unit TEXT, through INTEGER)",
    *terms.schema(TERMS, texts=False),
    *row_codec.schema(),
    *key_namespaces.schema(),
]
# the database's own, beside each report's tables
OWN_TABLES = ("report_state", "report_changes", *terms.tables(TERMS, texts=False), DICTIONARIES, KEY_NAMESPACES)


def chunks(items: Sequence[Any], size: int = 500) -> Iterable[Sequence[Any]]:
    """`items` a few hundred at a time: a statement binds at most so many of SQLite's parameters."""
    for start in range(0, len(items), size):
        yield items[start : start + size]
