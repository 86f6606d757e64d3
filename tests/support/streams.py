"""Reading Server-Sent Events in tests, over real HTTP (a read that waits too long fails instead of hanging)."""

from __future__ import annotations

import threading

import httpx


def first_event(url: str, headers: dict[str, str], opened: threading.Event | None = None) -> dict[str, str]:
    """The first event of a stream (its `id`, `event` and `data` fields); fails when the stream ends first.
    `opened` is set once the stream answered: where it starts is then fixed, later changes are sent."""
    event: dict[str, str] = {}
    with httpx.stream("GET", url, headers=headers, timeout=30) as stream:
        assert stream.status_code == 200
        if opened is not None:
            opened.set()
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
