"""Ingest figures: latency of small posts (embedded store and Virtuoso) and of a cumulative re-publish.

python -m bench.ingest_figures [--posts 300] [--exchanges 80]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import httpx

from backend.api.app import create_app
from backend.config import Settings
from backend.store.oxigraph import OxigraphStore
from backend.store.virtuoso import VirtuosoStore
from bench.workloads import cumulative_graph, event_deltas, run_exchange
from tests.support.live_server import LiveServer
from tests.support.virtuoso import VirtuosoProcess


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q / 100 * (len(ordered) - 1)))]


def small_posts(url: str, payloads: list[str]) -> dict[str, float]:
    latencies = []
    with httpx.Client(base_url=url) as client:
        for payload in payloads[:20]:  # warm-up, on their own graph content
            client.post("/ttl", json={"ttl_content": payload.replace("mirror", "warmup")})
        for payload in payloads:
            started = time.perf_counter()
            client.post("/ttl", json={"ttl_content": payload, "user": "bench"}).raise_for_status()
            latencies.append((time.perf_counter() - started) * 1000)
    return {
        "n": len(latencies),
        "triples_mean": statistics.mean(p.count(" .\n") + p.count(" ;\n") for p in payloads),
        "p50_ms": percentile(latencies, 50),
        "p99_ms": percentile(latencies, 99),
        "max_ms": max(latencies),
    }


def cumulative_republish(url: str, exchanges: int, repeats: int = 10) -> dict[str, float]:
    robot = cumulative_graph(exchanges)
    with httpx.Client(base_url=url, timeout=120) as client:
        client.post("/ttl", json={"ttl_content": robot.logger.serialize()}).raise_for_status()
        latencies, sizes, new = [], [], []
        for index in range(exchanges, exchanges + repeats):
            run_exchange(robot, index)
            payload = robot.logger.serialize()
            started = time.perf_counter()
            answer = client.post("/ttl", json={"ttl_content": payload}).json()
            latencies.append((time.perf_counter() - started) * 1000)
            sizes.append(answer["triples_received"])
            new.append(answer["triples_new"])
    return {
        "payload_triples": statistics.mean(sizes),
        "new_triples": statistics.mean(new),
        "p50_ms": percentile(latencies, 50),
        "max_ms": max(latencies),
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--posts", type=int, default=300)
    parser.add_argument("--exchanges", type=int, default=80)
    args = parser.parse_args()
    payloads = list(event_deltas(args.posts))
    settings = Settings(_env_file=None, secret_key="")  # type: ignore[call-arg]
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        stores = {"oxigraph": lambda: OxigraphStore(settings.graph_uri, root / "ox")}
        virtuoso = VirtuosoProcess(root)
        virtuoso.start()
        stores["virtuoso"] = lambda: VirtuosoStore(
            endpoint=virtuoso.endpoint, user="dba", password="dba", graph_uri=settings.graph_uri
        )
        try:
            for name, make in stores.items():
                store = make()
                with LiveServer(create_app(settings, store=store)) as server:
                    print(name, "small posts", small_posts(server.url, payloads))
                    store.clear()
                    print(name, "cumulative re-publish", cumulative_republish(server.url, args.exchanges))
                store.close()
        finally:
            virtuoso.stop()


if __name__ == "__main__":
    main()
