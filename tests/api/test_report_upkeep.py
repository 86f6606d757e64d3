"""Keeping a report current costs the same for a robot's hundredth post as for its first: the keys a post
touches (named by the live stream's change events) stay a handful, however much the robot logged before.
Before, a new activity touched every state of its robot and every message with a sender (a chain from a hub,
and a UNION branch the post's values did not bind), so the upkeep grew with the log until it fell behind."""

from __future__ import annotations

import json
import threading
import time

import httpx

from bench.workloads import live_posts
from tests.support.live_server import LiveServer
from tests.support.settle import settle

POSTS = 40


def test_the_keys_a_post_touches_do_not_grow_with_the_log(memory_api: LiveServer) -> None:
    touched: list[tuple[str, int]] = []  # (report, keys) per change event
    client = httpx.Client(timeout=60)

    def listen() -> None:
        try:
            with client.stream("GET", f"{memory_api.url}/reports/stream") as stream:
                for line in stream.iter_lines():
                    if line.startswith("data:") and '"units"' in line:
                        change = json.loads(line.removeprefix("data:"))
                        touched.append((change["report"], len(change["units"])))
        except httpx.HTTPError:
            return  # closed below, once every post is in

    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    time.sleep(0.5)
    for post in live_posts(POSTS):
        answer = httpx.post(f"{memory_api.url}/ttl", content=post.payload, headers={"Content-Type": "text/turtle"})
        assert answer.status_code == 201, answer.text
        settle(memory_api.url)
        time.sleep(0.3)  # one poll of the stream per post: each event holds one post's keys
    client.close()
    listener.join(timeout=10)
    by_report: dict[str, list[int]] = {}
    for report, keys in touched:
        by_report.setdefault(report, []).append(keys)
    assert {"conversations", "robot-states", "emotion-timeline"} <= set(by_report)
    late = {report: max(sizes[len(sizes) // 2 :]) for report, sizes in by_report.items()}
    assert all(keys <= 4 for keys in late.values()), late
