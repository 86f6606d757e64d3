"""Waiting until a server has applied its journal and brought its reports up to date."""

from __future__ import annotations

import time

import httpx


def settle(base_url: str, timeout: float = 60) -> None:
    """Return once readiness shows no apply lag, no reports lag and no view being built (posts are then in
    every view)."""
    deadline = time.monotonic() + timeout
    while True:
        answer = httpx.get(f"{base_url}/healthz/ready", timeout=10)
        body = answer.json()
        caught_up = not {"apply_lag", "reports_lag", "views_building"} & set(body)
        if answer.status_code == 200 and caught_up:
            return
        if time.monotonic() > deadline:
            raise AssertionError(f"the server did not settle within {timeout} s: {body}")
        time.sleep(0.02)
