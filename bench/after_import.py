"""A robot's messages in the conversations report right after a large import: each view at its own pace.

    python -m bench.after_import                        # 900 interactions imported (about 120,000 triples)
    python -m bench.after_import --interactions 300     # a smoke run

`segb serve --only api` on a fresh embedded store (the views in their own process, as `segb serve` runs them).
One robot's history is imported as one N-Triples post; as soon as it is acknowledged, a second robot publishes
one interaction every 0.1 s (its new triples, by the PyPI client through the emotion-mirror robot), and a reader
asks the conversations report, filtered to that robot, until each post's utterance is there. Printed: the time
from each 201 to the utterance in the report (p50, p95, max), and the views readiness named behind meanwhile.
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from pathlib import Path

import httpx
from pyoxigraph import RdfFormat, parse, serialize

from bench.measure import Latency
from bench.server import segb_server
from bench.workloads import cumulative_posts
from tests.support.robot_posts import recording_mission, run_exchange, turtle

ROBOT = "greeter"
POST_SECONDS = 0.1


def imported(interactions: int) -> bytes:
    """One robot's history after `interactions`, as N-Triples."""
    *_, last = cumulative_posts(interactions, "importer")
    return serialize(parse(last.payload.encode(), RdfFormat.TURTLE), format=RdfFormat.N_TRIPLES) or b""


def fresh_posts(count: int) -> list[tuple[str, str]]:
    """`count` posts of the second robot: each one interaction's new triples, and its utterance's text."""
    robot, recording = recording_mission(ROBOT)
    posts = [(turtle(recording.take(), recording), "")]
    for index in range(count):
        run_exchange(robot, index)
        posts.append((turtle(recording.take(), recording), f"Utterance {index}: I passed my driving test!"))
    first, rest = posts[0][0], posts[1:]
    return [(first + rest[0][0], rest[0][1]), *rest[1:]]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--interactions", type=int, default=900)
    parser.add_argument("--posts", type=int, default=50)
    args = parser.parse_args(argv)
    history = imported(args.interactions)
    posts = fresh_posts(args.posts)
    with tempfile.TemporaryDirectory(prefix="segb-bench-") as scratch, segb_server("oxigraph", Path(scratch)) as server:
        client = httpx.Client(base_url=server.url, timeout=600)
        robot_iri = _robot_iri(posts[0][0])
        _warm_up(client)
        began = time.monotonic()
        answer = client.post("/ttl", content=history, headers={"Content-Type": "application/n-triples"})
        answer.raise_for_status()
        triples = history.count(b"\n")
        print(f"import: {triples:,} triples acknowledged in {time.monotonic() - began:.1f} s")
        behind: set[str] = set()
        watching = threading.Event()
        watcher = threading.Thread(target=_watch_readiness, args=(server.url, behind, watching), daemon=True)
        watcher.start()
        delays = _post_and_read(client, posts, robot_iri)
        watching.set()
        watcher.join()
        latency = Latency.of(delays)
        print(f"201 to the utterance in the conversations report, {len(delays)} posts at {1 / POST_SECONDS:.0f}/s: "
              f"p50 {latency.p50:.0f} ms, p95 {latency.p95:.0f} ms, max {latency.max:.0f} ms")  # fmt: skip
        print(f"views readiness named behind meanwhile: {', '.join(sorted(behind)) or 'none'}")
    return 0


def _warm_up(client: httpx.Client) -> None:
    """A first post, and its views built: the import then meets views kept current, as on a server running a while
    (the views' process starts after the API answers)."""
    client.post("/ttl", json={"ttl_content": "<urn:bench:warm> <urn:bench:up> 1 .", "user": "bench"}).raise_for_status()
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        body = client.get("/healthz/ready").json()
        if not {"views_building", "reports_lag", "apply_lag"} & set(body):
            return
        time.sleep(0.2)
    raise RuntimeError(f"the views were not built: {body}")


def _robot_iri(first_post: str) -> str:
    robots = [
        quad.subject.value
        for quad in parse(first_post.encode(), RdfFormat.TURTLE)
        if quad.predicate.value == "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
        and quad.object.value.endswith("#Robot")
    ]
    return robots[0]


def _post_and_read(client: httpx.Client, posts: list[tuple[str, str]], robot: str) -> list[float]:
    """Post at the pace set, and time each post's utterance into the report (a reader thread per post)."""
    delays: list[float] = []
    readers = []
    for payload, text in posts:
        started = time.monotonic()
        client.post("/ttl", json={"ttl_content": payload, "user": ROBOT}).raise_for_status()
        acknowledged = time.monotonic()
        reader = threading.Thread(target=_read_until, args=(client, robot, text, acknowledged, delays), daemon=True)
        reader.start()
        readers.append(reader)
        time.sleep(max(0.0, POST_SECONDS - (time.monotonic() - started)))
    for reader in readers:
        reader.join(timeout=120)
    return delays


def _read_until(client: httpx.Client, robot: str, text: str, since: float, delays: list[float]) -> None:
    while time.monotonic() - since < 120:
        rows = client.get("/reports/conversations", params={"robot": robot, "limit": 1000}).json()["rows"]
        if any(row.get("text") == text for row in rows):
            delays.append(time.monotonic() - since)
            return
        time.sleep(0.02)


def _watch_readiness(url: str, behind: set[str], done: threading.Event) -> None:
    while not done.wait(0.2):
        body = httpx.get(f"{url}/healthz/ready", timeout=10).json()
        behind.update(body.get("views_lag", {}))


if __name__ == "__main__":
    raise SystemExit(main())
