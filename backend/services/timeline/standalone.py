"""A timeline as one self-contained HTML file: its rows, the viewer's script and style inline, nothing to fetch.

It opens in a browser with no server (an evidence bundle carries one): the same viewer as the web UI's
/timeline page (viewer/timeline.js: ruler, zoom, keyboard playhead, filters, #t= deep links). Its
Content-Security-Policy lets only its own script and style run and fetches nothing. The rows are data, not
markup: robot text reaches the page as JSON and is set as text.
"""

from __future__ import annotations

import base64
import hashlib
import json
from collections.abc import Mapping, Sequence
from functools import cache
from importlib.resources import files

from jinja2 import Template
from markupsafe import Markup

from segb_server.backend.services.direction_controls import page_environment
from segb_server.backend.services.timeline.kinds import KINDS

# The page's own look: the web UI's colours and type, as far as a page with one section needs them.
BASE_STYLE = """
body { margin: 0; color: #1d2433; background: #f5f7fa; font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto,
  "DejaVu Sans", sans-serif; }
main { padding: 1.2rem 1.6rem 3rem; max-width: 90rem; margin: 0 auto; }
h1 { font-size: 1.5rem; margin: 0 0 0.4rem; }
.lead { color: #5b6478; margin-top: 0; }
a { color: #2f5fd0; }
dl.facts { display: grid; grid-template-columns: max-content 1fr; gap: 0.2rem 1rem; font-size: 0.9rem; }
dl.facts dt { color: #5b6478; }
dl.facts dd { margin: 0; }
"""


@cache
def viewer_file(name: str) -> str:
    """One of the viewer's files (timeline.js, timeline.css), which the web UI's page loads too."""
    return (files("segb_server.backend.services.timeline") / "viewer" / name).read_text(encoding="utf-8")


@cache
def _template() -> Template:
    environment = page_environment(keep_trailing_newline=True)  # a robot's direction controls shown as marks
    return environment.from_string(viewer_file("standalone.html"))


def _hash(text: str) -> str:
    """A Content-Security-Policy source for exactly this inline text."""
    return "sha256-" + base64.b64encode(hashlib.sha256(text.encode("utf-8")).digest()).decode("ascii")


def _data(rows: Sequence[Mapping[str, object]]) -> Markup:
    """The rows as a JSON data block: no `<`, `>` or `&` left in it, so no text can end the block."""
    text = json.dumps(list(rows), ensure_ascii=False, separators=(",", ":"))
    return Markup(text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026"))


def _linked(row: Mapping[str, object], link_base: str | None) -> dict[str, object]:
    """A row with its explanation and graph links on `link_base` (a server's web UI), or none: a file opened
    offline has no server to ask."""
    linked = dict(row)
    for name in ("explain", "graph"):
        href = row.get(name)
        linked[name] = f"{link_base.rstrip('/')}{href}" if link_base and isinstance(href, str) else None
    return linked


def standalone_html(
    rows: Sequence[Mapping[str, object]],
    *,
    title: str,
    subject: str = "",
    since: str | None = None,
    until: str | None = None,
    kinds: Sequence[str] = KINDS,
    truncated: bool = False,
    generated_at: str | None = None,
    generator: str | None = None,
    link_base: str | None = None,
) -> str:
    """The timeline of `rows` (as `GET /timeline` gives them, in its order) as one HTML document.

    `title` and `subject` head the page (escaped); `since`/`until` are the window (ISO 8601), the ruler's ends
    when given; `truncated` says the window holds more events than `rows`; `generated_at` and `generator` say
    when and by whom it was written; `link_base` (a web UI's address) keeps each row's links to its explanation
    and graph, which are otherwise left out."""
    script = viewer_file("timeline.js")
    style = BASE_STYLE + viewer_file("timeline.css")
    return _template().render(
        title=title,
        subject=subject,
        since=since,
        until=until,
        kinds=list(kinds),
        count=len(rows),
        truncated=truncated,
        generated_at=generated_at,
        generator=generator,
        data=_data([_linked(row, link_base) for row in rows]),
        script=Markup(script),
        style=Markup(style),
        script_hash=_hash(script),
        style_hash=_hash(style),
    )
