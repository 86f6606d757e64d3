"""The matching policy (thresholds, window, namespace) and how observations are normalised for it."""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from datetime import UTC, datetime

from segb_server.backend.config import Settings

# The reference backend's rule set, kept so clients and auditors can tell which rules decided.
RESOLVER_VERSION = "shared-context-v1-rules"
WEIGHTS = {"time": 0.30, "text": 0.35, "subject": 0.20, "modality": 0.10}
CANDIDATE_WINDOW_FACTOR = 2.0  # contexts within ±2 windows are scored; beyond that the time term is 0 anyway
MAX_CANDIDATES_PER_CASE = 4

_NOT_WORD = re.compile(r"[^\w\s]+")
_SPACES = re.compile(r"\s+")
_NOT_SLUG = re.compile(r"[^a-z0-9]+")


@dataclass(frozen=True)
class Policy:
    namespace: str
    time_window_seconds: float = 3.0
    match_threshold: float = 0.85
    ambiguous_threshold: float = 0.70
    close_margin: float = 0.05
    strict_modality: bool = False

    @classmethod
    def from_settings(cls, settings: Settings) -> Policy:
        return cls(
            namespace=settings.shared_context_namespace,
            time_window_seconds=settings.shared_context_time_window_seconds,
            match_threshold=settings.shared_context_match_threshold,
            ambiguous_threshold=settings.shared_context_ambiguous_threshold,
            close_margin=settings.shared_context_close_margin,
            strict_modality=settings.shared_context_strict_modality_mismatch,
        )

    @property
    def candidate_span(self) -> float:
        return CANDIDATE_WINDOW_FACTOR * self.time_window_seconds


def atom(value: str | None) -> str | None:
    """Kinds, subjects and modalities compare trimmed and lower-cased; blank means absent."""
    if value is None:
        return None
    value = value.strip().lower()
    return value or None


def scoring_text(value: str | None) -> str | None:
    """Lower-cased, punctuation turned into spaces, whitespace collapsed; blank means absent."""
    if value is None:
        return None
    value = _SPACES.sub(" ", _NOT_WORD.sub(" ", value.lower())).strip()
    return value or None


def slug(event_kind: str) -> str:
    return _NOT_SLUG.sub("_", event_kind.lower()).strip("_") or "event"


def epoch(moment: datetime) -> float:
    """Seconds since the epoch; a naive time is taken as UTC (as robots' clocks usually are)."""
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return moment.timestamp()


def digest(*parts: object) -> str:
    return hashlib.sha256("|".join(str(part) for part in parts).encode("utf-8")).hexdigest()
