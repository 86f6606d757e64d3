"""A person's data as one page they can read and keep: self-contained HTML (no script, no outside resource),
every value from the log escaped, its direction controls shown as marks."""

from __future__ import annotations

from collections.abc import Mapping

from segb_server.backend.services.clock import utc_iso
from segb_server.backend.services.direction_controls import page_environment
from segb_server.backend.services.people.export import PersonData
from segb_server.backend.vocabulary import compact

# The page's one stylesheet is inline (it opens with no server); it has no script, so a policy allowing only that
# style is what serves it.
PAGE_POLICY = "default-src 'none'; style-src 'unsafe-inline'; img-src data:; base-uri 'none'; form-action 'none'"

# A robot's direction controls are shown as marks (direction_controls.py): a name with an override would turn the
# page's own sentences around.
_PAGE = page_environment().from_string(
    """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>What the robots' log holds about {{ name }}</title>
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<style>
body{font:15px/1.5 system-ui,sans-serif;max-width:60rem;margin:2rem auto;padding:0 1rem;color:#1b1f24}
table{border-collapse:collapse;width:100%}th,td{text-align:left;padding:.35rem .5rem;border-bottom:1px solid #d0d7de;
vertical-align:top}th{background:#f3f5f7}code{font-size:.85em;word-break:break-all}.muted{color:#57606a}
</style></head><body>
<h1>What the robots' log holds about {{ name }}</h1>
<p>Person <code>{{ data.human }}</code>. Exported {{ exported }} from this SEGB server: {{ data.triples|length }}
statements, listed below in full, and what they tell in time order.</p>
<h2>In time order</h2>
{% if rows %}<table><thead><tr><th>When (UTC)</th><th>What</th></tr></thead><tbody>
{% for row in rows %}<tr><td>{{ row.time or "time not logged" }}</td><td>{{ row.sentence }}</td></tr>
{% endfor %}</tbody></table>{% else %}<p class="muted">Nothing with a time.</p>{% endif %}
<h2>Every statement</h2>
<table><thead><tr><th>Subject</th><th>Property</th><th>Value</th></tr></thead><tbody>
{% for t in triples %}<tr><td><code>{{ t[0] }}</code></td><td><code>{{ t[1] }}</code></td>
<td><code>{{ t[2] }}</code></td></tr>
{% endfor %}</tbody></table>
</body></html>
"""
)


def story_page(data: PersonData) -> str:
    name = data.name or "this person"
    rows = [{"time": row.get("time"), "sentence": _sentence(row, name)} for row in data.story]
    triples = [(str(t.subject).strip("<>"), compact(t.predicate.value), _value(t.object)) for t in data.triples]
    return _PAGE.render(data=data, name=name, rows=rows, triples=triples, exported=utc_iso(timespec="seconds"))


def _sentence(row: Mapping[str, object], name: str) -> str:
    """One honest sentence per row: a robot is named only for what the log says it did, a model only beside the
    reading it made."""
    robot = row.get("robotName") or row.get("robot") or "a robot"
    kind = row.get("kind")
    if kind == "said":
        return f"{name} said to {robot}: “{row.get('text')}”"
    if kind == "replied":
        return f"{robot} replied: “{row.get('text')}”"
    if kind == "emotion":
        category = str(row.get("category", "")).rsplit("#", 1)[-1].removeprefix("big6_")
        intensity = f" ({row['intensity']})" if row.get("intensity") is not None else ""
        model = row.get("modelName") or row.get("model")
        version = f" {row['modelVersion']}" if row.get("modelVersion") else ""
        by = f" with the model {model}{version}" if model else ""
        return f"{robot} read the emotion {category}{intensity} on {name}{by}"
    if row.get("text"):
        return f"{robot} observed: {row.get('text')}"
    return f"{robot} detected {name}"


def _value(term: object) -> str:
    text = str(term)
    return text.strip("<>") if text.startswith("<") else text
