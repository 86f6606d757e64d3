"""Webhooks for findings: each new finding at or above WEBHOOK_MIN_SEVERITY, and each such finding later
resolved, posted to every WEBHOOK_URLS as signed JSON (`signing.py`), without ever holding a post up."""

from __future__ import annotations

from collections.abc import Callable
from urllib.parse import quote

from segb_server.backend.config import Settings
from segb_server.backend.services.observability.deliveries import Deliveries
from segb_server.backend.services.observability.finding_changes import FindingChanges, at_least
from segb_server.backend.services.rules.findings import Finding
from segb_server.backend.services.rules.service import FindingsService


def payload(found: Finding, explain_base: str) -> dict[str, object]:
    """What a receiver is told of one finding: the human by the pseudonymous IRI the log gives, never a name."""
    focus = found.get("focus")
    return {
        "rule": found.get("rule"),
        "severity": found.get("severity"),
        "title": found.get("title"),
        "robot": found.get("robot"),
        "human": found.get("human"),
        "focus": focus,
        "message": found.get("message"),
        "time": found.get("time"),
        "explain": f"{explain_base}/explain?iri={quote(str(focus), safe='')}" if focus else None,
    }


class Webhooks:
    def __init__(self, settings: Settings, findings: FindingsService, leading: Callable[[], bool]) -> None:
        self.deliveries = Deliveries(settings.webhook_url_list, settings.webhook_secret)
        explain_base = settings.effective_backend_url
        self.changes = FindingChanges(
            findings,
            at_least(settings.webhook_min_severity),
            lambda event, found: self.deliveries.send(event, payload(found, explain_base)),
            leading,
        )

    def start(self) -> None:
        self.deliveries.start()
        self.changes.start()

    def stop(self) -> None:
        self.changes.stop()
        self.deliveries.stop()
