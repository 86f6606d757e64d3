"""The webhooks' signature: HMAC-SHA256 over the timestamp and the body, as Stripe signs its events.

Header `X-SEGB-Signature: t=<unix seconds>,v1=<hex>` where `<hex>` is HMAC-SHA256(WEBHOOK_SECRET,
"<t>.<raw body>"). A receiver recomputes it over the raw body it received, compares in constant time, and
refuses a timestamp older than it tolerates (five minutes here): a captured delivery cannot be replayed later.
"""

from __future__ import annotations

import hashlib
import hmac
import time

HEADER = "X-SEGB-Signature"
TOLERANCE_SECONDS = 300


def signature(secret: str, body: bytes, timestamp: int | None = None) -> str:
    """The header's value for `body` sent at `timestamp` (now when not given)."""
    moment = int(time.time()) if timestamp is None else timestamp
    digest = hmac.new(secret.encode(), f"{moment}.".encode() + body, hashlib.sha256).hexdigest()
    return f"t={moment},v1={digest}"


def verified(secret: str, body: bytes, header: str, now: float | None = None) -> bool:
    """Whether `header` signs `body` with `secret` within the tolerance of `now`."""
    fields = dict(part.split("=", 1) for part in header.split(",") if "=" in part)
    stamp, given = fields.get("t", ""), fields.get("v1", "")
    if not stamp.isdigit() or abs((time.time() if now is None else now) - int(stamp)) > TOLERANCE_SECONDS:
        return False
    expected = signature(secret, body, int(stamp)).partition(",v1=")[2]
    return hmac.compare_digest(expected, given)
