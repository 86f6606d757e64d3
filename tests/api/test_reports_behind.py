"""While the views are behind the log, a report says so — how far, in posts and in time — instead of silently
showing old rows: in the API's answer (`behind`) and on the UI's report pages."""

from __future__ import annotations

import time

import httpx

from segb_server.backend.api.app import create_app
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.ui.app import create_ui_app
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.scenarios import publish_message
from tests.support.settle import settle


def test_rows_behind_the_log_say_how_far_on_the_api_and_on_the_page() -> None:
    store = OxigraphStore("http://amor-segb/events")
    app = create_app(make_settings(), store=store)
    try:
        with LiveServer(app) as api:
            publish_message(api.url, "Before the views stopped.")
            settle(api.url)
            current = httpx.get(f"{api.url}/reports/conversations", timeout=30).json()
            assert current["served_from"] == "rows" and current["behind"] is None

            app.state.services.writes.keeper.stop()  # the views stop following: posts now wait for them
            publish_message(api.url, "After the views stopped.")
            time.sleep(0.2)  # a moment for the post to be waited on
            answer = httpx.get(f"{api.url}/reports/conversations", timeout=30).json()
            assert answer["served_from"] == "rows"
            assert answer["behind"]["entries"] == 1 and answer["behind"]["seconds"] >= 0.2, answer["behind"]
            assert "After the views stopped." not in str(answer["rows"])  # what it says is why

            with LiveServer(create_ui_app(make_settings(backend_url=api.url))) as ui:
                for path in ("/reports/conversations", "/reports"):
                    page = httpx.get(f"{ui.url}{path}", timeout=30).text
                    assert "s behind what robots have published (1 post on the way)" in page, path
    finally:
        store.close()
