"""Sending spans over OTLP/HTTP, and reading the log's activities as spans (for a window, or one activity)."""

from __future__ import annotations

from collections.abc import Sequence

from opentelemetry.exporter.otlp.proto.http.trace_exporter import OTLPSpanExporter
from opentelemetry.sdk.trace import ReadableSpan
from opentelemetry.sdk.trace.export import SpanExportResult

from segb_server.backend.services.observability.spans import Row
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.terms import bind_values

QUERY = "traces/activities"
BATCH = 512  # spans in one request


class ExportFailed(RuntimeError):
    """The OTLP endpoint did not take the spans (its own retries included)."""


def exporter(endpoint: str) -> OTLPSpanExporter:
    """The OTLP/HTTP exporter for `endpoint` (OTEL_EXPORTER_OTLP_ENDPOINT: traces go to its /v1/traces, as the
    specification says); OpenTelemetry's other OTEL_EXPORTER_OTLP_* settings (headers, timeout, compression)
    apply as the library reads them."""
    return OTLPSpanExporter(endpoint=endpoint.rstrip("/") + "/v1/traces")


def send(export: OTLPSpanExporter, spans: Sequence[ReadableSpan]) -> None:
    for start in range(0, len(spans), BATCH):
        if export.export(spans[start : start + BATCH]) is not SpanExportResult.SUCCESS:
            raise ExportFailed(f"the OTLP endpoint refused or did not answer ({len(spans)} spans)")


def rows(store: Store, query: CatalogQuery, filters: dict[str, str | None]) -> list[Row]:
    """The activities' rows under `filters` (robot, activity, since, until)."""
    return select(store, bind_values(query.text, query.bindings(filters))).rows
