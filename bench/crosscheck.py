"""A filtered report page that came back empty, checked against the report's own query run through `/sparql`
with the same filter bound: an empty page should mean the query has no rows either."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import httpx

from bench.server import ROOT

REPORTS = ROOT / "sparql" / "reports"
SAME_AS = re.compile(r"^# same-as: reports/(\S+)$", re.MULTILINE)
XSD = "http://www.w3.org/2001/XMLSchema#"
TERMS = {"since": "dateTime", "until": "dateTime", "threshold": "decimal"}


def query_text(report: str, folder: Path = REPORTS) -> str | None:
    """The report's query (following `# same-as:`), or None when this checkout has no such file."""
    path = folder / f"{report}.rq"
    if not path.exists():
        return None
    text = path.read_text(encoding="utf-8")
    if same := SAME_AS.search(text):
        return query_text(same[1], folder)
    return text


def bound(text: str, filters: dict[str, str]) -> str:
    """The query with each filter bound by a VALUES row at the top of its WHERE, as `?param_<name>`."""
    values = "".join(f"\n  VALUES ?param_{name} {{ {_term(name, value)} }}" for name, value in filters.items())
    where = text.index("WHERE {") + len("WHERE {")
    return text[:where] + values + text[where:]


def _term(name: str, value: str) -> str:
    kind = TERMS.get(name)
    return f'"{value}"^^<{XSD}{kind}>' if kind else f"<{value}>"


UNCHECKED = -1  # the query could not be run (no such file here, or /sparql refused or timed out)


def check_of(page: Any) -> int | None:
    """A measured page's check: None for a page that needs none (rows, no filter, or a failed request), the
    query's row count, or UNCHECKED (also for an empty filtered page measured without a check)."""
    if page.rows or page.variant == "default" or getattr(page, "failure", None):
        return None
    checked = getattr(page, "query_rows", None)
    return UNCHECKED if checked is None else checked


def rows_of_query(client: httpx.Client, report: str, filters: dict[str, str]) -> int:
    """How many rows the report's query answers with the filters bound, or UNCHECKED."""
    text = query_text(report)
    if text is None:
        return UNCHECKED
    answer = client.get(
        "/sparql", params={"query": bound(text, filters)}, headers={"Accept": "application/sparql-results+json"}
    )
    if answer.status_code != 200:
        return UNCHECKED
    return len(answer.json()["results"]["bindings"])
