"""Unicode's explicit direction controls in the sentences the server composes around what robots wrote.

A right-to-left override (U+202E) in a robot's name or text turns what follows it around on screen, up to the
end of the paragraph: quoted inside a sentence of the server's ("TIAGo never answered Eve: …"), it would turn
the server's own words around too, and an auditor would read something neither the robot nor the server said.
The embeddings, overrides and isolates (U+202A to U+202E, U+2066 to U+2069) are therefore shown in those sentences as
visible marks (`[U+202E]`); the log keeps the text as sent, and the tables that show a robot's text in a cell
of its own (which ends any direction it opens) show it as sent. Marks of direction that open nothing (U+200E,
U+200F) are left alone.
"""

from __future__ import annotations

import re

_CONTROLS = re.compile("[\u202a-\u202e\u2066-\u2069]")


def shown(sentence: str) -> str:
    """`sentence` with each explicit direction control written as a visible mark."""
    return _CONTROLS.sub(lambda found: f"[U+{ord(found.group()):04X}]", sentence)
