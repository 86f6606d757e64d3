#!/usr/bin/env python3
"""Regenerate docs/screenshots/phoenix-interaction.png: Arize Phoenix showing one robot's interaction as SEGB
traces it (README, "Watching SEGB from your tools").

Starts Phoenix from its own virtual environment (tests/observability/phoenix.py installs it from
tests/phoenix/requirements.lock), serves the API with the demo dataset and OTEL_EXPORTER_OTLP_ENDPOINT pointing at
Phoenix, opens an interaction of ARI's in headless Chromium with its model's span selected, and photographs it.
Usage, from the repository root: `python3 scripts/phoenix_screenshot.py` (`--chromium PATH`, `--out FILE`).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import httpx
from playwright.sync_api import sync_playwright

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from segb_server.backend.api.app import create_app  # noqa: E402
from tests.conftest import make_settings  # noqa: E402
from tests.observability.phoenix import PhoenixProcess  # noqa: E402
from tests.support.in_process import InProcess  # noqa: E402

ARI = "https://example.org/segb/robots/ari/v1/robot_ari"
VIEWPORT = {"width": 1440, "height": 900}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chromium", default="/usr/bin/chromium", help="Chromium binary (default /usr/bin/chromium)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "screenshots" / "phoenix-interaction.png")
    args = parser.parse_args()
    phoenix = PhoenixProcess()
    phoenix.start()
    try:
        with InProcess(create_app(make_settings(otel_exporter_otlp_endpoint=phoenix.url), demo=True)):
            spans = phoenix.spans_when("segb", 40)
        time.sleep(2)
        spans = phoenix.spans("segb")
        response = next(
            span for span in spans
            if span["name"] == "response" and span["attributes"].get("segb.robot") == ARI  # type: ignore[union-attr]
        )  # fmt: skip
        trace = response["context"]["trace_id"]  # type: ignore[index]
        project = next(p for p in httpx.get(f"{phoenix.url}/v1/projects").json()["data"] if p["name"] == "segb")
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=args.chromium, args=["--no-sandbox"])
            page = browser.new_page(viewport=VIEWPORT)  # type: ignore[arg-type]
            page.goto(f"{phoenix.url}/projects/{project['id']}/traces/{trace}", wait_until="networkidle")
            page.wait_for_timeout(3000)
            page.get_by_text("inference Emotion", exact=False).first.click()  # the model's span: its gen_ai.*
            page.get_by_role("tab", name="Attributes").first.click()
            page.wait_for_timeout(1500)
            page.screenshot(path=str(args.out))
            browser.close()
    finally:
        phoenix.stop()
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
