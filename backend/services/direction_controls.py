"""Unicode's explicit direction controls in what robots wrote, as every page the server renders shows them.

A right-to-left override (U+202E) in a robot's name or text turns what follows it around on screen, up to the
end of the paragraph: quoted inside a sentence of the server's ("TIAGo never answered Eve: …") or beside the
page's own words (a conversation's header, "TIAGo ↔ Eve"), it would turn those around too, and an auditor would
read something neither the robot nor the server said. The embeddings, overrides and isolates (U+202A to U+202E,
U+2066 to U+2069) are therefore shown as visible marks (`[U+202E]`): in the sentences the API composes, and in
everything a page writes, through the pages' one template environment (`page_environment`), so no page or
template can forget it. The log, the JSON answers and the RDF exports keep the text as sent. Marks of direction
that open nothing (U+200E, U+200F) are left alone.

This module depends on nothing of the project's: the web UI, a client of the API, uses the same rule.
"""

from __future__ import annotations

import re
from typing import Any

from jinja2 import BaseLoader, Environment
from markupsafe import Markup

_CONTROLS = re.compile("[\u202a-\u202e\u2066-\u2069]")


def shown(sentence: str) -> str:
    """`sentence` with each explicit direction control written as a visible mark."""
    return _CONTROLS.sub(lambda found: f"[U+{ord(found.group()):04X}]", sentence)


class AsTyped(str):
    """Text a viewer typed, written back exactly (a query in its editor, to run again unchanged): never a robot's."""


def shown_on_page(value: Any) -> Any:
    """Every value a page writes (Jinja's `finalize`), direction controls shown: text and markup alike, the marks
    being plain text. Other values have none to show until written, and are written as they are."""
    if isinstance(value, AsTyped):
        return str(value)
    if isinstance(value, str) and hasattr(value, "__html__"):  # Markup: built by the page, its values inside it
        return Markup(shown(str(value)))
    if isinstance(value, str):
        return shown(value)
    return value


def page_environment(loader: BaseLoader | None = None, **options: Any) -> Environment:
    """The template environment of every page: autoescaped, direction controls shown in all it writes."""
    environment = Environment(loader=loader, autoescape=True, finalize=shown_on_page, **options)
    environment.filters["as_typed"] = AsTyped
    return environment
