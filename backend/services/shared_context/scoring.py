"""Scoring how likely two observations are the same event: time, text, subject and modality terms."""

from __future__ import annotations

from dataclasses import dataclass
from difflib import SequenceMatcher
from typing import Protocol

from segb_server.backend.services.shared_context.policy import WEIGHTS, Policy


class Observed(Protocol):
    """What scoring reads from a new observation or a stored context."""

    @property
    def event_kind(self) -> str: ...
    @property
    def observed_at(self) -> float: ...
    @property
    def subject(self) -> str | None: ...
    @property
    def modality(self) -> str | None: ...
    @property
    def canonical_text(self) -> str | None: ...


@dataclass(frozen=True)
class Score:
    context_uri: str
    total: float
    breakdown: dict[str, float]


def clash(left: str | None, right: str | None) -> bool:
    return left is not None and right is not None and left != right


def may_match(new: Observed, stored: Observed, policy: Policy, span: float) -> bool:
    """The hard filters: same kind, close in time, and no contradicting subject (or modality, when strict)."""
    return (
        new.event_kind == stored.event_kind
        and abs(new.observed_at - stored.observed_at) <= span
        and not clash(new.subject, stored.subject)
        and not (policy.strict_modality and clash(new.modality, stored.modality))
    )


def score(new: Observed, stored: Observed, stored_uri: str, window: float) -> Score:
    """Weighted mean of the available terms; without text on both sides the text term is left out."""
    delta = abs(new.observed_at - stored.observed_at)
    breakdown = {
        "time": max(0.0, 1.0 - delta / window) if window > 0 and delta < window else 0.0,
        "subject": _agreement(new.subject, stored.subject),
        "modality": _agreement(new.modality, stored.modality),
    }
    if new.canonical_text and stored.canonical_text:
        breakdown["text"] = text_similarity(new.canonical_text, stored.canonical_text)
    weight = sum(WEIGHTS[term] for term in breakdown)
    total = sum(WEIGHTS[term] * value for term, value in breakdown.items()) / weight
    return Score(stored_uri, total, breakdown)


def text_similarity(left: str, right: str) -> float:
    """Half token-set Jaccard (word choice), half sequence ratio (word order and spelling)."""
    left_tokens, right_tokens = set(left.split()), set(right.split())
    jaccard = len(left_tokens & right_tokens) / len(left_tokens | right_tokens)
    return 0.5 * jaccard + 0.5 * SequenceMatcher(None, left, right).ratio()


def ranked(scores: list[Score]) -> list[Score]:
    # Ties are broken by URI so the same state always gives the same ranking.
    return sorted(scores, key=lambda found: (-found.total, found.context_uri))


def decisive(scores: list[Score], policy: Policy) -> bool:
    """The best (of ranked scores) is good enough and clearly ahead of the runner-up."""
    if not scores or scores[0].total < policy.match_threshold:
        return False
    return len(scores) == 1 or scores[0].total - scores[1].total >= policy.close_margin


def _agreement(left: str | None, right: str | None) -> float:
    if left is None or right is None:
        return 0.5
    return 1.0 if left == right else 0.0
