"""Keeping a report current costs the same for a robot's hundredth post as for its first: the keys a post
touches (named by the live stream's change events) stay a handful, however much the robot logged before.
Before, a new activity touched every state of its robot and every message with a sender (a chain from a hub,
and a UNION branch the post's values did not bind), so the upkeep grew with the log until it fell behind."""

from __future__ import annotations

import json
import threading

import httpx
import pytest

from tests.support.live_server import LiveServer
from tests.support.robot_posts import live_posts
from tests.support.settle import settle

POSTS = 40


@pytest.mark.slow  # forty posts, each followed on the live stream
def test_the_keys_a_post_touches_do_not_grow_with_the_log(live_api: LiveServer) -> None:
    touched: list[tuple[str, int]] = []  # (report, keys) per change event
    heard = threading.Condition()  # notified at each id the stream gives, and when it opens
    positions: list[int] = []
    opened = threading.Event()
    client = httpx.Client(timeout=60)

    def listen() -> None:
        try:
            with client.stream("GET", f"{live_api.url}/reports/stream") as stream:
                opened.set()  # the stream's start is read before its headers go out: later changes are sent
                for line in stream.iter_lines():
                    if line.startswith("data:") and '"units"' in line:
                        change = json.loads(line.removeprefix("data:"))
                        touched.append((change["report"], len(change["units"])))
                    elif line.startswith("id:"):
                        with heard:
                            positions.append(int(line.removeprefix("id:")))
                            heard.notify_all()
        except httpx.HTTPError:
            return  # closed below, once every post is in

    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    assert opened.wait(timeout=30)
    for post in live_posts(POSTS):
        answer = live_api.post("/ttl", content=post.payload, headers={"Content-Type": "text/turtle"})
        assert answer.status_code == 201, answer.text
        settle(live_api.url)
        # Each post's changes are heard before the next post: each event holds one post's keys. (A post that
        # changes no report's rows, as the robot's description alone, is announced by none: nothing to hear.)
        included = live_api.get("/reports/conversations", params={"limit": 1}).json()["last_event_id"]
        with heard:
            assert heard.wait_for(lambda at=included: at == 0 or (bool(positions) and positions[-1] >= at), timeout=30)
    client.close()
    listener.join(timeout=10)
    by_report: dict[str, list[int]] = {}
    for report, keys in touched:
        by_report.setdefault(report, []).append(keys)
    assert {"conversations", "robot-states", "emotion-timeline"} <= set(by_report)
    late = {report: max(sizes[len(sizes) // 2 :]) for report, sizes in by_report.items()}
    assert all(keys <= 4 for keys in late.values()), late
