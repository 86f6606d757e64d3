"""The window's events as one self-contained HTML page for an evidence bundle (no script, no outside resource,
every value escaped). One function, so a fuller rendering of the timeline can take its place."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from segb_server.backend.services.direction_controls import page_environment
from segb_server.backend.services.values import JsonValue

_PAGE = page_environment().from_string(
    """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Timeline — {{ title }}</title>
<link rel="icon" href="data:,"><style>
body{font:14px/1.45 system-ui,sans-serif;margin:1.5rem;color:#1b1f24}table{border-collapse:collapse;width:100%}
th,td{text-align:left;padding:.3rem .5rem;border-bottom:1px solid #d0d7de;vertical-align:top}th{background:#f3f5f7}
code{font-size:.85em;word-break:break-all}.kind{white-space:nowrap;color:#57606a}
</style></head><body>
<h1>Timeline — {{ title }}</h1>
<p>{{ rows|length }} events in time order, as the robots logged them. The triples behind them are in
<code>triples.nt</code>, checked against the server's receipts by <code>segb verify-evidence</code>.</p>
<table><thead><tr><th>Time (UTC)</th><th>Kind</th><th>Robot</th><th>What</th><th>Resource</th></tr></thead><tbody>
{% for row in rows %}<tr><td>{{ row.time }}</td><td class="kind">{{ row.kind }}</td><td>{{ row.robot or "" }}</td>
<td>{{ row.text or row.label or "" }}</td><td><code>{{ row.item }}</code></td></tr>
{% endfor %}</tbody></table></body></html>
"""
)


def render_timeline(title: str, rows: Sequence[Mapping[str, JsonValue]]) -> str:
    """`rows`: time, kind, item, and where known robot, text, label (the window query's columns)."""
    return _PAGE.render(title=title, rows=rows)
