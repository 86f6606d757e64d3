"""Waiting until a server has applied its journal and brought its reports up to date."""

from __future__ import annotations

import sys
import threading
import time
import traceback

from tests.support.in_process import Server, http


def settle(server: Server, timeout: float = 60) -> None:
    """Return once readiness shows no apply lag, no reports lag and no view being built (posts are then in
    every view). `server`: a live server's URL, or the client of an app served in process."""
    deadline = time.monotonic() + timeout
    while True:
        answer = http(server, "GET", "/healthz/ready", timeout=10)
        body = answer.json()
        caught_up = not {"apply_lag", "reports_lag", "views_building"} & set(body)
        if answer.status_code == 200 and caught_up:
            return
        if time.monotonic() > deadline:
            raise AssertionError(f"the server did not settle within {timeout} s: {body}\n{server_threads()}")
        time.sleep(0.02)


def server_threads() -> str:
    """Where each of the server's own threads is (`segb-*`: the applier, the views and their workers), for a
    test's servers run in this process: what a server that does not settle is waiting for."""
    frames = sys._current_frames()
    stacks = [
        f"thread {thread.name}:\n" + "".join(traceback.format_stack(frames[thread.ident])[-12:])
        for thread in threading.enumerate()
        if thread.name.startswith("segb") and thread.ident in frames
    ]
    return "\n".join(stacks) or "(no server thread in this process)"


def kept_rows(server: Server, report: str, timeout: float = 60) -> None:
    """Return once `report` is served from its kept rows: they are built as the server starts, a moment after it
    answers (until then the report is evaluated in full, and readiness tells no lag: `settle` after this)."""
    deadline = time.monotonic() + timeout
    while http(server, "GET", f"/reports/{report}", params={"limit": 1}).json()["served_from"] != "rows":
        if time.monotonic() > deadline:
            raise AssertionError(f"{report} was not served from its rows within {timeout} s")
        time.sleep(0.02)


def findings_built(server: Server, timeout: float = 60) -> None:
    """Return once no audit rule's findings are still being first built (the views a server builds as it starts;
    `settle` after this)."""
    deadline = time.monotonic() + timeout
    while "building" in http(server, "GET", "/findings", params={"limit": 1}).json()["served_from"].values():
        if time.monotonic() > deadline:
            raise AssertionError(f"the findings were still being built after {timeout} s")
        time.sleep(0.02)
