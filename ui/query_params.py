"""Filter values from a page's query string, as the API wants them."""

from __future__ import annotations

import re

from fastapi import Request

_HAS_ZONE = re.compile(r"(Z|[+-]\d\d:?\d\d)$")
TIME_NAMES = ("since", "until")


def query_values(request: Request, names: tuple[str, ...], times: tuple[str, ...] = TIME_NAMES) -> dict[str, str]:
    """The non-empty values of `names`, trimmed. A time (one of `times`) picked in the browser has no zone:
    pages label times as UTC, so it gets one."""
    values = {name: request.query_params.get(name, "").strip() for name in names}
    for name in times:
        if values.get(name) and not _HAS_ZONE.search(values[name]):
            values[name] += "Z"
    return {name: value for name, value in values.items() if value}
