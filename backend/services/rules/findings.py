"""What one finding is, whichever rule made it, and the order findings are listed in.

A finding is a rule's row: `focus` (what it is about), `message`, and, where the rule tells them, `time`,
`robot` and `human`; whatever else the row holds are its `values` (a delay, a category, a SHACL path and value).
"""

from __future__ import annotations

from datetime import UTC, datetime

from segb_server.backend.services import direction_controls
from segb_server.backend.services.rules.catalog import LISTED_COLUMNS, REQUIRED_COLUMNS, Rule
from segb_server.backend.services.values import JsonValue

Finding = dict[str, object]
_OWN = {*REQUIRED_COLUMNS, *LISTED_COLUMNS}


def finding(rule: Rule, row: dict[str, JsonValue]) -> Finding:
    """A rule's row as the API lists it."""
    return {
        "rule": rule.id,
        "severity": rule.severity,
        "title": rule.title,
        "focus": row.get("focus"),
        "message": direction_controls.shown(message) if isinstance(message := row.get("message"), str) else message,
        "time": row.get("time"),
        "robot": row.get("robot"),
        "human": row.get("human"),
        "values": {name: value for name, value in row.items() if name not in _OWN and value is not None},
    }


def order_key(row: dict[str, JsonValue]) -> tuple[object, ...]:
    """The order of findings across rules: by time (a finding without one first), then by what it is about —
    the order each rule's own rows are in (`ORDER BY ?time ?focus`), so rules' pages merge."""
    return (*_time_key(row.get("time")), str(row.get("focus") or ""))


def _time_key(value: JsonValue) -> tuple[int, object]:
    if value is None:
        return (0, "")
    if isinstance(value, bool):
        return (5, str(value))
    if isinstance(value, int | float):
        return (3, float(value))
    try:
        moment = datetime.fromisoformat(value.replace("Z", "+00:00"))
    except ValueError:
        return (5, value)
    if moment.tzinfo is None:
        return (5, value)
    return (4, moment.astimezone(UTC))
