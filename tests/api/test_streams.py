"""The event streams' inputs, over real HTTP (a stream read waits with a time limit): an unknown report is refused up
front, and a resume position the server does not know (garbage, or from before a restart) never fails the stream. A
change wakes the streams of the process that made it at once, without waiting for their next look. A report page tells
where its stream resumes."""

from __future__ import annotations

import json
import threading
import time

import httpx
import pytest

from segb_server.backend.api.routes import live
from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby, publish_message
from tests.support.settle import settle
from tests.support.streams import events_until_quiet, first_event


def test_an_unknown_report_is_refused_before_the_stream_opens(live_api: LiveServer) -> None:
    answer = httpx.get(f"{live_api.url}/reports/stream", params={"report": "no-such-report"}, timeout=30)
    assert (answer.status_code, answer.json()["error"]) == (404, "not_found")


def test_a_graph_stream_resumed_from_an_unknown_position_says_fetch_again(live_api: LiveServer) -> None:
    lobby().publish_all(live_api.url)
    through = httpx.get(f"{live_api.url}/graph").json()["through"]
    for position in ("garbage", "-1", "99999999"):
        event = first_event(f"{live_api.url}/graph/stream", {"Last-Event-ID": position})
        assert (event["event"], int(event["id"])) == ("change", through)


GARBAGE_POSITIONS = {
    "word": "garbage",
    "negative": "-1",
    "decimal": "1.5",
    "20 digits": "9" * 20,
    "5000 digits": "9" * 5000,
}


@pytest.mark.parametrize("position", GARBAGE_POSITIONS.values(), ids=GARBAGE_POSITIONS.keys())
def test_a_report_stream_with_a_garbage_position_starts_from_now(live_api: LiveServer, position: str) -> None:
    """Past SQLite's integers (20 digits) or Python's digit limit (5,000) a position is garbage too."""
    lobby().publish_all(live_api.url)
    with httpx.stream(
        "GET", f"{live_api.url}/reports/stream", headers={"Last-Event-ID": position}, timeout=30
    ) as stream:
        assert stream.status_code == 200
        lines = stream.iter_lines()
        assert next(lines) == "retry: 2000"  # no reset, no replay: nothing to resume from
        publish_message(live_api.url, "After a garbage position")  # and later changes still arrive
        deadline = time.monotonic() + 20  # a keep-alive comment every 15 s gives the loop a turn
        while not next(lines).startswith("event: change"):
            assert time.monotonic() < deadline, "no change was announced"


def test_a_post_wakes_both_streams_without_polling(live_api: LiveServer, monkeypatch: pytest.MonkeyPatch) -> None:
    """Polling stretched past the readers' patience (30 s): the posts still reach them, woken by the views."""
    monkeypatch.setattr(live, "POLL_SECONDS", 600.0)
    settle(live_api.url)  # the views are built (empty)
    heard: dict[str, dict[str, str] | BaseException] = {}
    paths = ("/reports/stream", "/graph/stream")
    opened = {path: threading.Event() for path in paths}

    def listen(path: str) -> None:
        try:
            heard[path] = first_event(f"{live_api.url}{path}", {}, opened[path])
        except BaseException as error:
            heard[path] = error
            opened[path].set()

    readers = [threading.Thread(target=listen, args=(path,)) for path in paths]
    for reader in readers:
        reader.start()
    assert all(event.wait(timeout=30) for event in opened.values())  # both are waiting
    lobby().publish_all(live_api.url)
    for reader in readers:
        reader.join(timeout=60)
    assert {path: type(event).__name__ for path, event in heard.items()} == {
        "/reports/stream": "dict",
        "/graph/stream": "dict",
    }, heard


def test_a_report_page_tells_where_its_stream_resumes(live_api: LiveServer) -> None:
    """A page's `last_event_id` is the stream position its rows include: resuming from it announces the next
    change, and a page read after that change includes it."""
    lobby().publish_all(live_api.url)
    page = httpx.get(f"{live_api.url}/reports/conversations", timeout=30).json()
    assert page["served_from"] == "rows" and page["last_event_id"] > 0
    before = page["last_event_id"]

    publish_message(live_api.url, "After the page")
    settle(live_api.url)

    event = first_event(f"{live_api.url}/reports/stream?report=conversations", {"Last-Event-ID": str(before)})
    assert event["event"] == "change" and int(event["id"]) > before
    later = httpx.get(f"{live_api.url}/reports/conversations", timeout=30).json()
    assert later["last_event_id"] >= int(event["id"])
    assert "After the page" in str(later["rows"]) and "After the page" not in str(page["rows"])


def test_a_reader_leaving_in_the_middle_of_a_batch_hears_the_rest_when_it_resumes(live_api: LiveServer) -> None:
    """One batch of the views can change several reports, sent as one event each: the id to resume from is on
    the batch's last event only, so a reader that leaves after the first resumes with the others."""
    lobby().publish_all(live_api.url)
    start = httpx.get(f"{live_api.url}/reports/conversations", timeout=30).json()["last_event_id"]
    publish_message(live_api.url, "Heard by several reports at once")
    settle(live_api.url)
    batch = events_until_quiet(f"{live_api.url}/reports/stream", {"Last-Event-ID": str(start)})
    changed = [json.loads(event["data"])["report"] for event in batch]
    assert {"conversations", "participants"} <= set(changed)

    first = batch[0]  # the reader left after this one, and resumes from the last id it was given
    resumed = events_until_quiet(f"{live_api.url}/reports/stream", {"Last-Event-ID": first.get("id", str(start))})
    assert set(changed[1:]) <= {json.loads(event["data"])["report"] for event in resumed}
    assert "id" in batch[-1] and all("id" not in event for event in batch[:-1])


def test_a_position_ahead_of_the_stream_says_reload_then_follows(live_api: LiveServer) -> None:
    """An id the stream has not reached (its rows were built again since the page was read) cannot tell what
    the reader missed: it is told to reload, and hears the changes that follow."""
    lobby().publish_all(live_api.url)
    newest = httpx.get(f"{live_api.url}/reports/conversations", timeout=30).json()["last_event_id"]
    with httpx.stream(
        "GET", f"{live_api.url}/reports/stream", headers={"Last-Event-ID": str(newest + 1000)}, timeout=30
    ) as stream:
        lines = stream.iter_lines()
        assert next(lines) == "event: reset"
        publish_message(live_api.url, "After the reset")
        deadline = time.monotonic() + 20  # a keep-alive comment every 15 s gives the loop a turn
        while not (line := next(lines)).startswith("id:"):
            assert time.monotonic() < deadline, "no change was announced"
        assert newest < int(line.split(":", 1)[1]) < newest + 1000
