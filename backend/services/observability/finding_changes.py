"""New and resolved findings, told as they happen: a thread follows the findings' change marks (the rows the
views keep say which rules changed) and compares each changed rule's findings with those it saw before.

What the rules found before the server started is what it starts from: only findings that appear or go while it
runs are told. While a rule's findings are being built (at start, after an erasure) they are read again as the
new starting point, not told: a build is not the log changing.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.rules.catalog import SEVERITIES, Rule
from segb_server.backend.services.rules.findings import Finding
from segb_server.backend.services.rules.service import FindingsService, Selection

logger = logging.getLogger("segb.webhooks")

POLL_SECONDS = 0.5
PAGE = 1000
NAMED_CHANGES = 1000  # the changes `changed_rules` reads at most: past that, every rule is compared

Told = Callable[[str, Finding], object]  # ("finding.new" or "finding.resolved", the finding)


def at_least(severity: str) -> tuple[str, ...]:
    """The severities as serious as `severity` or more."""
    return SEVERITIES[: SEVERITIES.index(severity) + 1]


class FindingChanges:
    def __init__(self, findings: FindingsService, severities: tuple[str, ...], tell: Told,
                 leading: Callable[[], bool] = lambda: True) -> None:  # fmt: skip
        self.findings = findings
        self.rules = [rule for rule in findings.catalog if rule.severity in severities]
        self.tell = tell
        self.leading = leading  # with several API processes only the one applying the journal tells
        self._seen: dict[str, dict[str, Finding]] = {}  # rule → focus → finding
        self._position = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="segb-finding-changes", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10)

    def _run(self) -> None:
        while not self._stop.wait(POLL_SECONDS):
            try:
                self.look()
            except OUTAGES as error:  # the views' storage or the store away: looked at again next time
                logger.warning("findings not compared: %s", error)

    def look(self) -> None:
        """Compare the rules that changed since the last look; tell what appeared and what went."""
        if not self.leading():
            self._seen.clear()  # another process tells; should this one lead later, it starts afresh
            self._position = ""
            return
        looked, (self._position, changed) = self._position, self.findings.changed_rules(self._position)
        everything = _many_changes(looked, self._position)
        for rule in [rule for rule in self.rules if everything or rule.id in changed or rule.id not in self._seen]:
            now, served = self._current(rule)
            if served == "query":  # not kept (KEEP_VIEWS=false): nothing marks its changes, so nothing is told
                self.rules.remove(rule)
                logger.warning("findings of rule %s are not kept: no webhook tells of them", rule.id)
                continue
            before = self._seen.pop(rule.id, None)
            if served != "rows":  # being built: no starting point until it is
                continue
            self._seen[rule.id] = now
            if before is None:
                continue
            for focus in sorted(now.keys() - before.keys()):
                self.tell("finding.new", now[focus])
            for focus in sorted(before.keys() - now.keys()):
                self.tell("finding.resolved", before[focus])

    def _current(self, rule: Rule) -> tuple[dict[str, Finding], str]:
        """The rule's findings by focus, and where they were read from ("rows", "building" or "query")."""
        found: dict[str, Finding] = {}
        after = None
        while True:
            page = self.findings.page(Selection([rule], {}), PAGE, after)
            served = page.served_from.get(rule.id, "rows")
            found.update({str(finding["focus"]): finding for finding in page.findings})
            if page.next is None or served != "rows":
                return found, served
            after = page.next


def _many_changes(before: str, now: str) -> bool:
    """More changes between two positions ('rows.shapes') than `changed_rules` names rules from."""
    try:
        return any(int(b) + NAMED_CHANGES <= int(n) for b, n in zip(before.split("."), now.split("."), strict=True))
    except ValueError:  # the first look: every rule is read anyway
        return False
