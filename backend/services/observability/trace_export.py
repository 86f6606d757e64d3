"""`segb export --otlp`: a window of what robots did, read from the store and sent as traces, on demand."""

from __future__ import annotations

from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.observability.otlp import QUERY, exporter, rows, send
from segb_server.backend.services.observability.spans import spans_of
from segb_server.backend.services.sparql.catalog import Catalog, check_window, to_term
from segb_server.backend.store.base import Store


class NoEndpoint(ValueError):
    """No OTLP endpoint to send to."""


def export_window(
    store: Store, catalog: Catalog, endpoint: str, filters: dict[str, str | None], *, with_text: bool
) -> int:
    """Send the traces of the activities in the window (`robot`, `since`, `until`); how many spans went.
    Raises InvalidParameter for a bad value, NoEndpoint without an endpoint, ExportFailed when it refuses."""
    if not endpoint:
        raise NoEndpoint("set OTEL_EXPORTER_OTLP_ENDPOINT (e.g. http://127.0.0.1:6006) to export traces")
    query = catalog.get(QUERY)
    for name, value in filters.items():
        if value is not None:
            parameter = query.parameters.get(name)
            if parameter is None:
                raise InvalidParameter(name, "not a filter of the traces")
            to_term(parameter, value)  # InvalidParameter naming a bad one
    check_window(filters.get("since"), filters.get("until"))
    spans = spans_of(rows(store, query, filters), with_text=with_text)
    export = exporter(endpoint)
    try:
        send(export, spans)
    finally:
        export.shutdown()
    return len(spans)
