"""How values look on pages: short names for IRIs, readable times. Registered as Jinja filters."""

from __future__ import annotations

import re
from collections.abc import Collection, Mapping
from datetime import UTC, datetime
from typing import Any
from urllib.parse import urlencode

from segb_server.ui.vocabulary import current


def short_iri(value: object) -> str:
    """`https://…/ari/v1/human_maria` → `human_maria`; known vocabularies as `prefix:name`."""
    text = str(value or "")
    if not text.startswith(("http://", "https://", "urn:")):
        return text
    compacted = current().compact(text)
    if compacted != text:
        return compacted
    tail = text.rstrip("/#").replace("#", "/").rsplit("/", 1)[-1]
    return tail or text


def iri_text(value: object) -> str:
    """An IRI so its owner can be told: `prefix:name` in a known vocabulary, else the whole IRI (the last part
    alone, `activity_respond_4`, does not say which robot's)."""
    text = str(value or "")
    return current().compact(text) if text.startswith(("http://", "https://", "urn:")) else text


_GENERATED = re.compile(r"[-_]?[0-9a-f]{12,}", re.IGNORECASE)


def iri_tail(iri: object) -> str:
    return str(iri or "").rstrip("/#").replace("#", "/").rsplit("/", 1)[-1]


def is_unnamed(iri: object, label: object) -> bool:
    """True when a label is only the IRI's last part: the log gave the resource no name."""
    return not label or str(label) == iri_tail(iri)


def id_words(iri: object) -> str:
    """The words of an unnamed resource's IRI without its generated id: `…/observation-041730fd31af` →
    `observation`, `…/human_utterance_2a72abaa3d6798df` → `human utterance`."""
    return re.sub(r"[-_]+", " ", _GENERATED.sub("", iri_tail(iri))).strip() or "unnamed"


def unnamed_label(node: Mapping[str, Any], robots: Collection[str]) -> str:
    """A node the log gave no name (`id`, `kind`, `time`) by its robot, kind and time: `ARI's state at
    10:00:03.500` (`State at …` when several robots or none are around it), else by `id_words`."""
    kind = str(node.get("kind") or "")
    if kind == "other" or not node.get("time"):
        return id_words(node["id"])
    whose = f"{', '.join(sorted(robots, key=str.casefold))}'s {kind}" if len(robots) == 1 else kind.capitalize()
    return f"{whose} at {when(node['time'], with_date=False)}"


def when(value: object, with_date: bool = True) -> str:
    """ISO time → `2026-03-10 09:00:05` (UTC, as stored)."""
    if not value:
        return ""
    try:
        moment = parse_time(str(value))
    except ValueError:
        return str(value)
    shown = moment.strftime("%Y-%m-%d %H:%M:%S" if with_date else "%H:%M:%S")
    return shown + (f".{moment.microsecond // 1000:03d}" if moment.microsecond else "")


def epoch_when(seconds: object) -> str:
    """Seconds since the epoch (a token's `exp`) → `2026-03-10 09:00:05` UTC."""
    if isinstance(seconds, bool) or not isinstance(seconds, int | float):
        return ""
    return when(datetime.fromtimestamp(seconds, UTC).isoformat())


def plural(count: object, one: str, many: str | None = None) -> str:
    """`1 triple`, `2 triples`: the count with the word that fits it."""
    return f"{count} {one if count == 1 else (many or one + 's')}"


def parse_time(value: str) -> datetime:
    return datetime.fromisoformat(value.replace("Z", "+00:00"))


def number(value: object, digits: int = 2) -> str:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return "" if value is None else str(value)
    return f"{value:.{digits}f}".rstrip("0").rstrip(".") if isinstance(value, float) else str(value)


def explain_href(iri: object) -> str:
    return "/explain?" + urlencode({"iri": str(iri)})


FILTERS = {
    "short_iri": short_iri,
    "iri_text": iri_text,
    "when": when,
    "epoch_when": epoch_when,
    "number": number,
    "plural": plural,
    "explain_href": explain_href,
}
