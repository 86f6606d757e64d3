"""Debian's headless Chromium as the tests and the bench drive it (Playwright's own browser download is not
used): its path, and the flags that keep it from reaching for the network at every start."""

from __future__ import annotations

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
