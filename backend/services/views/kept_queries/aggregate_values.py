"""An aggregate report's values as its tables hold them: each contribution's argument as stored (`aggregate_input`),
the SQL that aggregates a group's contributions (`sql_aggregate`), and a group's aggregate read back as a value of
the report's row (`aggregate_output`)."""

from __future__ import annotations

import json
import struct

from segb_server.backend.services.values import JsonValue, iso_time, json_value
from segb_server.backend.services.views.kept_queries.encoding import instant_of_part, sort_key
from segb_server.backend.store.base import Term
from segb_server.backend.store.terms import term_text


def aggregate_input(function: str, term: Term | None) -> str | None:
    if term is None:
        return None
    if function == "count":
        return term_text(term)
    if function == "sample":
        return json.dumps(json_value(term))
    return sort_key([term])


def sql_aggregate(function: str, distinct: bool, column: str) -> str:
    if function == "count":
        return f"COUNT({'DISTINCT ' if distinct else ''}{column})"
    return f"{'MAX' if function == 'max' else 'MIN'}({column})"  # MIN serves SAMPLE: any value will do


def aggregate_output(function: str, value: object) -> JsonValue:
    if value is None:
        return None
    if function == "count":
        return int(value)  # type: ignore[call-overload]
    if function == "sample":
        loaded: JsonValue = json.loads(str(value))
        return loaded
    return _decoded(str(value))


def _decoded(key: str) -> JsonValue:
    """The JSON value a one-term sort key stands for (the inverse of encoding._sort_part)."""
    kind, text = key[0], key[1:]
    if kind == "2":
        return text
    if kind == "3":
        bits = int(text, 16)
        bits = bits ^ (1 << 63) if bits >> 63 else bits ^ 0xFFFFFFFFFFFFFFFF
        return struct.unpack(">d", struct.pack(">Q", bits))[0]
    if kind == "4":
        return iso_time(instant_of_part(text))
    return text
