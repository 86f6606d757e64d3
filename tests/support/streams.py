"""Reading Server-Sent Events in tests."""

from __future__ import annotations

import httpx


def first_event(url: str, headers: dict[str, str]) -> dict[str, str]:
    """The first event of a stream (its `id`, `event` and `data` fields); fails when the stream ends first."""
    event: dict[str, str] = {}
    with httpx.stream("GET", url, headers=headers, timeout=30) as stream:
        assert stream.status_code == 200
        for line in stream.iter_lines():
            if line.startswith(("id:", "event:", "data:")):
                key, _, value = line.partition(":")
                event[key] = value.strip()
            elif not line and "event" in event:
                return event
    raise AssertionError("the stream ended")


def events_until_quiet(url: str, headers: dict[str, str], quiet: float = 1.0) -> list[dict[str, str]]:
    """The events a stream sends until it has been quiet for `quiet` seconds (what a reader replays on opening)."""
    events: list[dict[str, str]] = []
    event: dict[str, str] = {}
    timeout = httpx.Timeout(30, read=quiet)
    with httpx.stream("GET", url, headers=headers, timeout=timeout) as stream:
        assert stream.status_code == 200
        try:
            for line in stream.iter_lines():
                if line.startswith(("id:", "event:", "data:")):
                    key, _, value = line.partition(":")
                    event[key] = value.strip()
                elif not line and "event" in event:
                    events.append(event)
                    event = {}
        except httpx.ReadTimeout:
            return events
    raise AssertionError("the stream ended")
