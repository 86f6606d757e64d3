"""What a serving API sends operators' tools, started and stopped with it: erasures counted as they are applied,
webhooks for findings, live traces of what robots did."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from segb_server.backend.services.container import Services
from segb_server.backend.services.observability.metrics import ERASURES
from segb_server.backend.services.observability.webhooks import Webhooks
from segb_server.backend.services.writing.applier import Applied

if TYPE_CHECKING:
    from segb_server.backend.services.observability.live_traces import LiveTraces

logger = logging.getLogger("segb.webhooks")


class Watching:
    def __init__(self, services: Services) -> None:
        self.services = services
        settings = services.settings
        self.webhooks = _webhooks(services) if settings.webhook_url_list else None
        self.traces = _live_traces(services) if settings.otel_exporter_otlp_endpoint else None
        services.writes.on_applied(self._applied)
        if self.webhooks is not None:
            self.webhooks.start()
        if self.traces is not None:
            self.traces.start()

    def close(self) -> None:
        if self.webhooks is not None:
            self.webhooks.stop()
        if self.traces is not None:
            self.traces.stop()

    def _applied(self, step: Applied) -> None:
        """In the applier's thread, after each step it wrote: it must not wait for anything."""
        if step.erased:
            ERASURES.inc()
            if self.webhooks is not None:
                self.webhooks.deliveries.forget()
        if self.traces is not None:
            self.traces.applied(step)


def _webhooks(services: Services) -> Webhooks | None:
    if not services.settings.keep_views:  # nothing marks which findings changed: they would be evaluated in full
        logger.warning("WEBHOOK_URLS is set but KEEP_VIEWS is off: no webhook is told of findings")
        return None
    writes = services.writes
    return Webhooks(services.settings, services.findings, lambda: writes.apply_leadership.held)  # one process tells


def _live_traces(services: Services) -> LiveTraces:
    # Imported only when traces are wanted: OpenTelemetry's exporter takes a quarter of a second to import.
    from segb_server.backend.services.observability.live_traces import LiveTraces
    from segb_server.backend.services.observability.otlp import QUERY

    settings = services.settings
    return LiveTraces(
        services.store,
        services.catalog.get(QUERY),
        settings.otel_exporter_otlp_endpoint,
        with_text=settings.trace_message_text,
    )
