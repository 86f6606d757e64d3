#!/usr/bin/env python3
"""Regenerate docs/screenshots/: every page of the web UI as a newcomer first sees it.

Starts `segb serve --demo` on free ports with a throwaway data directory, runs the example robot against it
(so namesakes and a second robot's log are there too), then photographs each page in headless Chromium (a
1280x800 window, pictures scaled to 960x600) and stops the server. Usage, from the repository root:
`python3 scripts/screenshots.py` (`--chromium PATH` for another browser binary, `--out DIR` for another folder).
"""

from __future__ import annotations

import argparse
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
from playwright.sync_api import Page, sync_playwright

ROOT = Path(__file__).resolve().parents[1]
VIEWPORT = {"width": 1280, "height": 800}
SCALE = 0.75  # pictures of 960x600 pixels: small files, text still legible
# (file name, path, what to do on the page before the picture)
PAGES = [
    ("reports", "/reports", None),
    ("report-emotion-timeline", "/reports/emotion-timeline", None),
    ("report-ml-usage", "/reports/ml-usage", None),
    ("report-robot-states", "/reports/robot-states", None),
    ("timeline", "/timeline?robot={robot}", "timeline"),
    ("findings", "/findings", None),
    ("graph", "/kg-graph", "graph"),
    ("explain", "/explain?iri={reply}", None),
    ("query", "/query?example=reports/participants&query={participants}", None),
    ("shared-context", "/shared-context", None),
    ("ledger", "/ledger", None),
    ("insert", "/logs/insert", "insert"),
    ("clear", "/logs/delete", None),
    ("people", "/people", None),
    ("logs", "/logs", None),
    ("session", "/session", None),
    ("health", "/health", None),
]
SAMPLE_LOG = (
    "@prefix foaf: <http://xmlns.com/foaf/0.1/> .\n"
    '<https://example.org/people/eve> a foaf:Person ; foaf:firstName "Eve" .\n'
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chromium", default="/usr/bin/chromium", help="Chromium binary (default /usr/bin/chromium)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "screenshots", help="where the PNGs go")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with demo_server() as (api, ui):
        robot = [sys.executable, "-m", "segb_server.examples.emotion_mirror.run", "--server", api]
        subprocess.run([*robot, "--ollama-host", f"http://127.0.0.1:{free_port()}"], check=True, capture_output=True)
        values = page_values(api)
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=args.chromium, args=["--no-sandbox"])
            page = browser.new_page(viewport=VIEWPORT, device_scale_factor=SCALE)
            for name, path, action in PAGES:
                page.goto(ui + path.format(**values))
                prepare(page, action)
                target = args.out / f"{name}.png"
                page.screenshot(path=str(target))
                print(f"{target.relative_to(ROOT) if target.is_relative_to(ROOT) else target}")
            browser.close()
    return 0


def prepare(page: Page, action: str | None) -> None:
    if action == "graph":
        page.wait_for_selector("#graph[data-ready=true]", timeout=60_000)
        # The drawing whole, from its toolbar down: it starts below the filters, past the window's bottom.
        page.evaluate("document.querySelector('.graph-toolbar').scrollIntoView()")
        page.wait_for_timeout(300)
    elif action == "timeline":
        page.wait_for_selector(".tl-row", timeout=60_000)
        page.focus(".tl-list")
        for _ in range(6):  # the playhead on an event, as an investigator steps through them
            page.keyboard.press("ArrowDown")
        page.wait_for_timeout(300)
    elif action == "insert":
        page.fill("#insert-text", SAMPLE_LOG)
        page.click("#insert-validate")
        page.wait_for_load_state()


def page_values(api: str) -> dict[str, str]:
    """IRIs and queries the pages above are opened with."""
    rows = httpx.get(f"{api}/reports/conversations", timeout=30).json()["rows"]
    reply = next(row["message"] for row in rows if row["speaker"] == "robot")
    query = "PREFIX foaf: <http://xmlns.com/foaf/0.1/>\nSELECT ?human ?name WHERE { ?human foaf:firstName ?name }"
    robot = next(row["robot"] for row in rows if row["speaker"] == "robot")
    return {
        "reply": str(httpx.QueryParams({"i": reply}))[2:],
        "participants": str(httpx.QueryParams({"q": query}))[2:],
        "robot": str(httpx.QueryParams({"r": robot}))[2:],
    }


@contextmanager
def demo_server() -> Iterator[tuple[str, str]]:
    api_port, ui_port = free_port(), free_port()
    with tempfile.TemporaryDirectory(prefix="segb-screenshots-") as data:
        ports = ["--api-port", str(api_port), "--ui-port", str(ui_port)]
        command = ["segb", "serve", "--demo", "--data-dir", data, *ports]
        server = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
        api, ui = f"http://127.0.0.1:{api_port}", f"http://127.0.0.1:{ui_port}"
        try:
            wait_for(f"{api}/healthz/ready")
            wait_for(f"{ui}/health")
            yield api, ui
        finally:
            server.terminate()
            server.wait(timeout=30)


def wait_for(url: str, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if httpx.get(url, timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    raise SystemExit(f"screenshots: {url} did not answer within {timeout:.0f} s")


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


if __name__ == "__main__":
    sys.exit(main())
