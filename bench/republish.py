"""The tutorial's robot, all day long: what the server's answer to a cumulative re-publish costs as the robot's
graph grows (`python -m bench --only republish`).

The robot is the emotion-mirror mission logging with the real PyPI client; after every interaction it publishes
`logger.serialize()`, its whole graph, as the tutorial's node does. At each size (interactions so far) the
server first gets the graph as grown so far, once, then `REPEATS` re-publishes, each one more
interaction than the last: their answer (wall time over loopback, the body encoded beforehand) and the API
process's CPU per post. "read whole" is one more re-publish whose header differs by a comment, so no block of
it is recognised: what every re-publish cost before blocks were skipped, and what the first re-publish after a
restart costs.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path

from semantic_log_generator import SEGBPublisher

from bench.client import Client
from bench.measure import Latency
from bench.probes import wait_caught_up
from bench.server import ServerProcess
from bench.tables import table
from segb_server.examples.emotion_mirror.publishing import NewOnly
from tests.support.robot_posts import mission, run_exchange

REPEATS = 8


@dataclass(frozen=True)
class Documents:
    """One size's documents: the graph after `interactions`, then one more interaction each."""

    interactions: int
    triples: int
    history: bytes  # request bodies, as the client sends them
    republished: list[bytes]
    serialize_seconds: float  # the client's own `serialize` of the largest of them (the robot's cost)
    new_only_seconds: float  # the robot's own cost of its last one as `--publish new` makes it (NewOnly)


@dataclass(frozen=True)
class Republish:
    interactions: int
    triples: int
    payload_mib: float
    answer: Latency
    cpu: Latency  # the API process's CPU per post
    whole_ms: float  # one re-publish read whole
    serialize_ms: float
    new_only_ms: float


def documents(sizes: tuple[int, ...], repeats: int = REPEATS) -> Iterator[Documents]:
    """Each size's documents, the robot's graph grown from the last size (made before any server measures)."""
    robot, done = mission("mirror"), 0
    new_only = NewOnly(SEGBPublisher(base_url="http://127.0.0.1:9"))  # only its documents are made
    for size in sizes:
        while done < size:
            run_exchange(robot, done)
            done += 1
        history = _body(robot.logger.serialize())
        new_only.document(robot.logger.graph)
        republished = []
        for _ in range(repeats):
            run_exchange(robot, done)
            done += 1
            started = time.perf_counter()
            new_only.document(robot.logger.graph)
            new_only_seconds = time.perf_counter() - started
            started = time.perf_counter()
            text = robot.logger.serialize()
            serialize_seconds = time.perf_counter() - started
            republished.append(_body(text))
        yield Documents(size, len(robot.logger.graph), history, republished, serialize_seconds, new_only_seconds)


def republish_runs(server: AbstractContextManager[ServerProcess], sizes: list[Documents]) -> list[Republish]:
    """Each size on one server, in order: the graph as grown posted once, then its re-publishes."""
    runs = []
    # A connection per request, as the client's `requests.post`: the views' catching up between posts outlasts
    # a kept-alive connection's idle timeout.
    with server as process, Client(process.url, connection_per_request=True) as client:
        assert process.pid is not None
        for docs in sizes:
            client.post("/ttl", docs.history, "application/json")
            wait_caught_up(process.url)
            seconds, cpu = [], []
            for body in docs.republished:
                spent, started = cpu_seconds(process.pid), time.perf_counter()
                client.post("/ttl", body, "application/json")
                seconds.append(time.perf_counter() - started)
                cpu.append(cpu_seconds(process.pid) - spent)
                wait_caught_up(process.url)  # the views' upkeep of one interaction stays out of the next answer
            started = time.perf_counter()
            client.post("/ttl", _read_whole(docs.republished[-1]), "application/json")
            whole_ms = (time.perf_counter() - started) * 1000
            wait_caught_up(process.url)
            runs.append(
                Republish(docs.interactions, docs.triples, len(docs.republished[-1]) / 2**20, Latency.of(seconds),
                          Latency.of(cpu), whole_ms, docs.serialize_seconds * 1000,
                          docs.new_only_seconds * 1000)
            )  # fmt: skip
    return runs


def cpu_seconds(pid: int) -> float:
    """The CPU a process's threads have run, in nanoseconds' resolution (/proc's clock ticks are 10 ms, as long
    as a whole answer)."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total += int((task / "schedstat").read_text().split()[0])
        except (FileNotFoundError, ProcessLookupError):  # a thread that ended meanwhile
            continue
    return total / 1e9


def republish_section(runs: dict[str, list[Republish]]) -> list[str]:
    if not runs:
        return []
    rows = []
    for label, measured in runs.items():
        first = measured[0].answer.p50
        for run in measured:
            rows.append([
                f"{label}, {run.interactions:,} interactions", f"{run.triples:,}", f"{run.payload_mib:.1f}",
                f"{run.answer.p50:.0f} / {run.answer.p95:.0f}", f"{run.cpu.p50:.0f} / {run.cpu.p95:.0f}",
                f"{run.answer.p50 / first:.2f}", f"{run.whole_ms:.0f}", f"{run.serialize_ms:.0f}",
                f"{run.new_only_ms:.0f}",
            ])  # fmt: skip
    return [
        "## Re-publishing the tutorial robot's whole graph",
        "",
        "One robot (the emotion mirror, the real client) publishes `logger.serialize()` after every interaction. "
        f"At each size, {REPEATS} re-publishes of one more interaction each: the answer (ms, p50 / p95), the API "
        "process's CPU per post (ms), the answer's ratio to the first size's, one re-publish read whole "
        "(a header the server has not seen: what every re-publish cost before re-sent blocks were skipped), and "
        "the robot's own cost of a publish (ms, in its process): the client's `serialize` of the whole graph, or "
        "the document of what is new (`--publish new`, examples/emotion_mirror/publishing.py).",
        "",
        *table(COLUMNS, rows),
    ]


COLUMNS = ["store, graph", "triples", "MiB", "answer p50 / p95", "CPU p50 / p95", "ratio to first", "read whole",
           "client: serialize", "client: new only"]  # fmt: skip


def _body(turtle: str) -> bytes:
    return json.dumps({"ttl_content": turtle, "user": "mirror"}).encode()


def _read_whole(body: bytes) -> bytes:
    document = json.loads(body)
    document["ttl_content"] = "# read whole\n" + document["ttl_content"]
    return json.dumps(document).encode()
