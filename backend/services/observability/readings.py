"""What a scrape reads as it happens: the write path's lag, the findings by rule and severity, the store's health.

Each is a cheap read: the lag from the write path's own bookkeeping, the findings from the rows the views keep
(a rule whose rows are not kept or not built yet is left out, never evaluated in full), the store's health by
one ping.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from prometheus_client.core import GaugeMetricFamily
from prometheus_client.metrics_core import Metric
from prometheus_client.registry import Collector

from segb_server.backend.services.container import Services
from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.observability.metrics import PREFIX
from segb_server.backend.services.rules.catalog import Rule
from segb_server.backend.services.rules.service import FindingsService
from segb_server.backend.state.database import StateUnavailable


class Readings(Collector):
    """The server's state as gauges, read from `services` at each scrape (blocking: run it off the event loop)."""

    def __init__(self, services: Services) -> None:
        self.services = services

    def collect(self) -> Iterator[Metric]:
        # The store or the journal away: the readings that need them are left out, the health says why.
        for reading in (self._lag, self._findings):
            with contextlib.suppress(*OUTAGES):
                yield from list(reading())  # read whole first: nothing of a failed reading is yielded
        yield from self._health()

    def _lag(self) -> Iterator[Metric]:
        lag = self.services.writes.lag()
        entries = GaugeMetricFamily(
            f"{PREFIX}_lag_entries", "Journal entries a stage has not taken in yet.", labels=["stage"]
        )
        seconds = GaugeMetricFamily(
            f"{PREFIX}_lag_seconds", "How long the oldest entry a stage misses has waited.", labels=["stage"]
        )
        entries.add_metric(["apply"], lag.apply_entries)  # the store behind the journal
        seconds.add_metric(["apply"], lag.apply_seconds)
        entries.add_metric(["views"], lag.views_entries)  # the views (reports, graph, findings) behind the store
        seconds.add_metric(["views"], lag.views_seconds)
        yield entries
        yield seconds
        view_entries = GaugeMetricFamily(
            f"{PREFIX}_view_lag_entries",
            "Entries the store has and one view misses (views behind only).",
            labels=["view"],
        )
        view_seconds = GaugeMetricFamily(
            f"{PREFIX}_view_lag_seconds", "How long the oldest entry one view misses has waited.", labels=["view"]
        )
        for view, (missed, waited) in sorted(self.services.writes.view_lags().items()):  # each view at its own pace
            view_entries.add_metric([view], missed)
            view_seconds.add_metric([view], waited)
        yield view_entries
        yield view_seconds

    def _findings(self) -> Iterator[Metric]:
        findings = self.services.findings
        family = GaugeMetricFamily(
            f"{PREFIX}_findings",
            "Findings the rules hold now, by rule and severity (rules whose findings are kept and built).",
            labels=["rule", "severity"],
        )
        for rule in findings.catalog:
            count = kept_count(findings, rule)
            if count is not None:
                family.add_metric([rule.id, rule.severity], count)
        yield family

    def _health(self) -> Iterator[Metric]:
        store = self.services.store
        up = GaugeMetricFamily(f"{PREFIX}_store_up", "1 while the triple store answers a ping.", labels=["store"])
        try:
            store.ping()
            up.add_metric([store.kind], 1)
        except OUTAGES:
            up.add_metric([store.kind], 0)
        yield up
        journal = self.services.writes.journal
        writable = GaugeMetricFamily(f"{PREFIX}_journal_up", "1 while the journal answers and has room to grow.")
        try:
            journal.ping()
            writable.add_metric([], 1 if journal.storage_ok() else 0)
        except StateUnavailable:
            writable.add_metric([], 0)
        yield writable


def kept_count(findings: FindingsService, rule: Rule) -> int | None:
    """A rule's findings counted from its kept rows; None when that would need evaluating the rule in full."""
    if rule.query is None:
        return findings.count(rule, {}) if findings.shapes is not None else None
    kept = findings.kept.reports.get(rule.query.name) if findings.kept is not None else None
    return findings.count(rule, {}) if kept is not None and kept.ready else None
