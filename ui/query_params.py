"""Filter values and page numbers from a page's query string, as the API wants them."""

from __future__ import annotations

import re

from fastapi import Request

_HAS_ZONE = re.compile(r"(Z|[+-]\d\d:?\d\d)$")
_SPACED_TIME = re.compile(r"^(\d{4}-\d\d-\d\d) (?=\d)")  # `2026-03-10 09:00:00`, as the tables show times
TIME_NAMES = ("since", "until")
MAX_PAGE_NUMBER_DIGITS = 18  # the API's integers; longer is no page number


def query_values(request: Request, names: tuple[str, ...], times: tuple[str, ...] = TIME_NAMES) -> dict[str, str]:
    """The non-empty values of `names`, trimmed. A time (one of `times`) typed as the tables show it, with a
    space for the `T` or with no zone, is made ISO 8601: pages label times as UTC, so it gets that zone."""
    values = {name: request.query_params.get(name, "").strip() for name in names}
    for name in times:
        if values.get(name):
            values[name] = _SPACED_TIME.sub(r"\1T", values[name])
            if not _HAS_ZONE.search(values[name]):
                values[name] += "Z"
    return {name: value for name, value in values.items() if value}


def paging(request: Request, default_limit: int, max_limit: int) -> tuple[int, int]:
    """The page's `limit` (1 to `max_limit`) and `offset`. A value that is not a whole number in ASCII digits
    (a word, `²`, fullwidth digits, thousands of digits) is the default: a URL edited by hand shows the first
    page instead of an error."""

    def whole(name: str, default: int) -> int:
        raw = request.query_params.get(name, "")
        return int(raw) if raw.isascii() and raw.isdigit() and len(raw) <= MAX_PAGE_NUMBER_DIGITS else default

    return max(1, min(whole("limit", default_limit), max_limit)), whole("offset", 0)
