"""While the views are behind the log, a report says so — how far, in posts and in time — instead of silently
showing old rows: in the API's answer (`behind`) and on the UI's report pages."""

from __future__ import annotations

import time

from segb_server.backend.api.app import create_app
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.in_process import UiOverApi
from tests.support.scenarios import publish_message
from tests.support.settle import kept_rows, settle


def test_rows_behind_the_log_say_how_far_on_the_api_and_on_the_page() -> None:
    store = OxigraphStore("http://amor-segb/events")
    settings = make_settings()
    app = create_app(settings, store=store)
    try:
        with UiOverApi(app, settings) as served:
            api = served.api
            publish_message(api, "Before the views stopped.")
            kept_rows(api, "conversations")  # the views built at start: from then on readiness tells their lag
            settle(api)
            current = api.get("/reports/conversations").json()
            assert current["served_from"] == "rows" and current["behind"] is None

            app.state.services.writes.keeper.stop()  # the views stop following: posts now wait for them
            publish_message(api, "After the views stopped.")
            time.sleep(0.2)  # the post waits that long, at least, which the answer must tell
            answer = api.get("/reports/conversations").json()
            assert answer["served_from"] == "rows"
            assert answer["behind"]["entries"] == 1 and answer["behind"]["seconds"] >= 0.2, answer["behind"]
            assert "After the views stopped." not in str(answer["rows"])  # what it says is why

            for path in ("/reports/conversations", "/reports"):
                page = served.get(path).text
                assert "s behind what robots have published (1 post on the way)" in page, path
    finally:
        store.close()
