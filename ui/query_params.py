"""Filter values and page numbers from a page's query string, as the API wants them."""

from __future__ import annotations

import re
from datetime import datetime

from fastapi import Request

# A time as the tables show it or as ISO 8601 writes it (the forms' inputs hold this pattern too).
TIME_PATTERN = r"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d{1,6})?)?(Z|[+\-]\d{2}:?\d{2})?"
TIME_EXAMPLE = "2026-03-10T09:00:00Z"
_HAS_ZONE = re.compile(r"(Z|[+-]\d\d:?\d\d)$")
_SPACED_TIME = re.compile(r"^(\d{4}-\d\d-\d\d) (?=\d)")  # `2026-03-10 09:00:00`, as the tables show times
TIME_NAMES = ("since", "until")
MAX_PAGE_NUMBER_DIGITS = 18  # the API's integers; longer is no page number


class BadFilter(ValueError):
    """A filter value the page cannot ask the API with; its message says which filter and what to type."""


def query_values(request: Request, names: tuple[str, ...], times: tuple[str, ...] = TIME_NAMES) -> dict[str, str]:
    """The non-empty values of `names`, trimmed. A time (one of `times`) typed as the tables show it, with a
    space for the `T` or with no zone, is made ISO 8601: pages label times as UTC, so it gets that zone. A time
    that is none raises BadFilter."""
    values = {name: request.query_params.get(name, "").strip() for name in names}
    for name in times:
        if values.get(name):
            values[name] = iso_time(name, values[name])
    return {name: value for name, value in values.items() if value}


def iso_time(name: str, typed: str) -> str:
    """`typed` as ISO 8601 in UTC unless it names its zone: `2026-03-10 09:00` → `2026-03-10T09:00Z`."""
    written = _SPACED_TIME.sub(r"\1T", typed)
    if not _HAS_ZONE.search(written):
        written += "Z"
    try:
        if re.fullmatch(TIME_PATTERN, typed):
            datetime.fromisoformat(written)
            return written
    except ValueError:
        pass
    raise BadFilter(
        f"{name.capitalize()} (UTC): \u201c{typed}\u201d is not a time. Type it as the tables show times, "
        f"e.g. {TIME_EXAMPLE} or 2026-03-10 09:00 (UTC unless it names its zone, as +01:00)."
    )


def paging(request: Request, default_limit: int, max_limit: int) -> tuple[int, int]:
    """The page's `limit` (1 to `max_limit`) and `offset`. A value that is not a whole number in ASCII digits
    (a word, `²`, fullwidth digits, thousands of digits) is the default: a URL edited by hand shows the first
    page instead of an error."""

    def whole(name: str, default: int) -> int:
        raw = request.query_params.get(name, "")
        return int(raw) if raw.isascii() and raw.isdigit() and len(raw) <= MAX_PAGE_NUMBER_DIGITS else default

    return max(1, min(whole("limit", default_limit), max_limit)), whole("offset", 0)
