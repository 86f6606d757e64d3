"""The `next` cursors of kept views' pages: the position of a page's last row (its sort key, unit and place), made
opaque for clients and checked when they pass it back."""

from __future__ import annotations

import base64
import json

from segb_server.backend.services.errors import InvalidParameter

NOT_A_CURSOR = "not a cursor this server made: pass the `next` of the previous page"


def cursor_of(order: str, unit: str | int, index: int) -> str:
    """Opaque and URL-safe: clients pass it back as it is."""
    return base64.urlsafe_b64encode(json.dumps([order, unit, index]).encode()).decode("ascii").rstrip("=")


def report_cursor(after: str) -> list[object]:
    """The position a report's `next` cursor names. Cursors come back from clients: anything but one this server
    made is refused by name."""
    decoded = _decoded(after)
    if not (
        isinstance(decoded, list)
        and len(decoded) == 3
        and isinstance(decoded[0], str)
        and isinstance(decoded[1], int)
        and 0 <= decoded[1] < 2**63  # a unit's number, within SQLite's integers
        and isinstance(decoded[2], int)
        and 0 <= decoded[2] < 2**63  # a row's index, within SQLite's integers
    ):
        raise InvalidParameter("after", NOT_A_CURSOR)
    return decoded


def findings_cursor(after: str) -> list[object]:
    """The position a SHACL rule's `next` cursor names (its unit is a node's text)."""
    decoded = _decoded(after)
    if not (isinstance(decoded, list) and len(decoded) == 3 and isinstance(decoded[2], int)):
        raise InvalidParameter("after", NOT_A_CURSOR)
    return decoded


def _decoded(after: str) -> object:
    """What a cursor spells, or None when it spells nothing."""
    try:
        return json.loads(base64.urlsafe_b64decode(after.encode("ascii") + b"=" * (-len(after) % 4)))
    except (ValueError, UnicodeError):  # binascii.Error and JSONDecodeError are ValueErrors
        return None
