"""The kinds of events on a timeline, in the order the events of one instant are told.

Each kind but `finding` is one query, `sparql/timeline/<kind>.rq`, kept as rows. At one instant, what an
activity was comes before what it used and produced: a shared event, then the activity (perception,
listening, decision, response, other), its models, observations, messages and emotions, then states and
findings.
"""

from __future__ import annotations

FOLDER = "timeline"
KINDS: tuple[str, ...] = (
    "shared-event",
    "perception",
    "listening",
    "decision",
    "response",
    "activity",
    "model",
    "observation",
    "message",
    "emotion",
    "state",
    "finding",
)
RANK = {kind: index for index, kind in enumerate(KINDS)}
FINDING = "finding"  # audit rules' findings: a source of their own once a findings service exists


def query_name(kind: str) -> str:
    return f"{FOLDER}/{kind}"
