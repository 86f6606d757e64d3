"""A live report page in headless Chromium, kept open as an auditor keeps it while a robot publishes: how long
after its 201 each post's messages show in the page, the whole way (the views, the API's stream, the UI's relay,
the page's script fetching its rows again, the browser drawing them)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from urllib.parse import urlencode

from playwright.sync_api import Error, Page, sync_playwright

from bench.measure import Latency
from tests.support.browser import CHROMIUM, CHROMIUM_ARGS

GRACE_SECONDS = 10.0  # after the watch: how long the posts answered last may still take to show

# Notes, in the page, when each message first shows: the message IRI of every conversation bubble's explain
# link → Date.now(). The page's clock and the bench's `time.time()` are the same system clock.
OBSERVER = """() => {
  window.__seen = {};
  const note = () => {
    const now = Date.now();
    document.querySelectorAll("#report-conversations a.explain-link").forEach((link) => {
      const iri = new URL(link.href).searchParams.get("iri");
      if (iri && !(iri in window.__seen)) window.__seen[iri] = now;
    });
  };
  note();
  new MutationObserver(note).observe(document.body, { childList: true, subtree: true });
}"""


@dataclass(frozen=True)
class InPage:
    """A post's messages in an open page: 201 to shown, of every post with messages answered while watched."""

    shown: Latency | None
    posts: int
    never_shown: int
    failure: str | None = None  # why nothing was watched (no Chromium, the page did not open)


def watch_conversations(
    ui_url: str, robot: str, answered: list[tuple[tuple[str, ...], float]], seconds: float
) -> InPage:
    """Open the robot's conversations with live updates on for `seconds`, and time its posts' messages into it.
    `answered`: the robot's posts with messages as it answers them, (their message IRIs, `time.time()` at the
    201), appended to by the robot's thread meanwhile."""
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            try:
                page = browser.new_page()
                page.goto(f"{ui_url}/reports/conversations?{urlencode({'robot': robot})}")
                page.wait_for_selector("#live-toggle[aria-pressed='true']")
                page.evaluate(OBSERVER)
                began = time.time()
                page.wait_for_timeout(seconds * 1000)
                ended = time.time()
                watched = [(messages, at) for messages, at in list(answered) if began <= at <= ended]
                seen = _seen_by(page, {message for messages, _ in watched for message in messages})
            finally:
                browser.close()
    except Error as error:
        return InPage(None, 0, 0, f"Chromium: {' '.join(str(error).split())[:200]}")
    if not watched:
        return InPage(None, 0, 0, "no post with messages was answered while the page was watched")
    delays = [
        max(seen[message] for message in messages) / 1000 - at
        for messages, at in watched
        if all(message in seen for message in messages)
    ]
    return InPage(Latency.of(delays) if delays else None, len(watched), len(watched) - len(delays))


def _seen_by(page: Page, wanted: set[str]) -> dict[str, float]:
    """What the page noted, once it shows every wanted message or the grace is over."""
    deadline = time.monotonic() + GRACE_SECONDS
    while True:
        seen: dict[str, float] = page.evaluate("window.__seen")
        if wanted <= seen.keys() or time.monotonic() > deadline:
            return seen
        page.wait_for_timeout(100)
