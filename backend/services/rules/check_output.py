"""What `segb check` prints: the findings of one log as text (one line each, like a compiler's), JSON, or JUnit
XML (one test case per rule, a failure per finding of severity violation, so a robot's CI shows them). Findings
are listed by line, as a reader goes down the file (POST /ttl/validate keeps them in time order)."""

from __future__ import annotations

import json
from xml.etree import ElementTree

from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.rules.findings import Finding
from segb_server.backend.services.rules.offline import CheckReport


def by_line(findings: list[Finding]) -> list[Finding]:
    """Top of the file first, then by rule and node; findings with no line (their node is not named in the
    file) last."""
    return sorted(
        findings, key=lambda found: (found["line"] is None, found["line"] or 0, found["rule"], found["focus"])
    )


def as_text(report: CheckReport, name: str) -> str:
    lines = []
    for found in by_line(report.findings):
        where = f"{name}:{found['line']}" if found.get("line") else name
        lines.append(f"{where}: {found['severity']}: [{found['rule']}] {found['message']} <{found['focus']}>")
    counts = {severity: 0 for severity in ("violation", "warning", "info")}
    for found in report.findings:
        counts[str(found["severity"])] += 1
    summary = ", ".join(f"{count} {severity}{'s' if count != 1 else ''}" for severity, count in counts.items())
    lines.append(f"{name}: {summary}")
    return "\n".join(lines) + "\n"


def as_json(report: CheckReport, name: str) -> str:
    document = {"file": name, "violations": report.violations, "findings": by_line(report.findings)}
    return json.dumps(document, indent=2, ensure_ascii=False) + "\n"


def as_junit(report: CheckReport, name: str, catalog: RuleCatalog) -> str:
    suite = ElementTree.Element("testsuite", name=f"segb check {name}")
    failures = 0
    for rule in catalog:
        case = ElementTree.SubElement(suite, "testcase", classname="segb.rules", name=rule.id)
        found = [item for item in by_line(report.findings) if item["rule"] == rule.id]
        if not found:
            continue
        text = "\n".join(f"{name}:{item.get('line') or '?'}: {item['message']} <{item['focus']}>" for item in found)
        if rule.severity == "violation":
            failures += 1
            failure = ElementTree.SubElement(case, "failure", message=f"{len(found)} finding(s): {rule.title}")
            failure.text = text
        else:
            ElementTree.SubElement(case, "system-out").text = text
    suite.set("tests", str(len(catalog)))
    suite.set("failures", str(failures))
    return ElementTree.tostring(suite, encoding="unicode") + "\n"
