"""The event streams' inputs: an unknown report is refused up front, and a resume position the server does not
know (garbage, or from before a restart) never fails the stream."""

from __future__ import annotations

import httpx

from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby
from tests.support.streams import first_event


def test_an_unknown_report_is_refused_before_the_stream_opens(memory_api: LiveServer) -> None:
    answer = httpx.get(f"{memory_api.url}/reports/stream", params={"report": "no-such-report"}, timeout=30)
    assert (answer.status_code, answer.json()["error"]) == (404, "not_found")


def test_a_graph_stream_resumed_from_an_unknown_position_says_fetch_again(memory_api: LiveServer) -> None:
    lobby().publish_all(memory_api.url)
    through = httpx.get(f"{memory_api.url}/graph").json()["through"]
    for position in ("garbage", "-1", "99999999"):
        event = first_event(f"{memory_api.url}/graph/stream", {"Last-Event-ID": position})
        assert (event["event"], int(event["id"])) == ("change", through)


def test_a_report_stream_with_a_garbage_position_starts_from_now(memory_api: LiveServer) -> None:
    lobby().publish_all(memory_api.url)
    with httpx.stream(
        "GET", f"{memory_api.url}/reports/stream", headers={"Last-Event-ID": "garbage"}, timeout=30
    ) as stream:
        assert stream.status_code == 200
        assert next(stream.iter_lines()) == "retry: 2000"  # no reset, no replay: nothing to resume from
