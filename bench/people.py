"""Erasing one person and exporting evidence, at a million triples, while a robot keeps posting.

    python -m bench.people                         # 10,000 visits of one person in a 1M-triple store
    python -m bench.people --visits 1000 --others 1000   # a smaller run

One robot (bench/one_robot.py's visit, made by the real client) has `--visits` visits from one regular visitor and
`--others` from visitors who come once, loaded as N-Triples posts into `segb serve --only api` on the embedded
store. Then, while another robot posts one visit every 0.1 s (each answer's latency and status recorded), the
regular visitor is erased (POST /humans/erase: its answer says how long each step took), the views are waited for,
and an evidence bundle of one hour of the robot is exported (GET /evidence) and checked offline. Prints markdown.
"""

from __future__ import annotations

import argparse
import re
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx

from bench.measure import machine, percentile
from bench.one_robot import SECONDS_PER_VISIT, T0, OneRobot, one_robot
from bench.server import segb_server
from segb_server.backend.services.evidence.verify import verify_bundle

VISITS_PER_POST = 400
REGULAR = "regular"


@dataclass
class Ingest:
    """A robot posting a visit every `interval` seconds until stopped."""

    url: str
    robot: OneRobot
    interval: float = 0.1
    latencies: list[float] = field(default_factory=list)
    statuses: list[int] = field(default_factory=list)
    _stop: threading.Event = field(default_factory=threading.Event)

    def run(self, start: int) -> None:
        with httpx.Client(base_url=self.url, timeout=120) as client:
            index = start
            while not self._stop.is_set():
                body = self.robot.visit(index).replace("robots/ari/", "robots/tiago/")
                began = time.perf_counter()
                try:
                    answer = client.post("/ttl", content=body, headers={"Content-Type": "application/n-triples"})
                    status = answer.status_code
                except httpx.HTTPError:
                    status = 0  # no answer within the client's 120 s
                self.latencies.append((time.perf_counter() - began) * 1000)
                self.statuses.append(status)
                index += 1
                self._stop.wait(self.interval)

    def stop(self) -> None:
        self._stop.set()


def regular_visit(robot: OneRobot, index: int) -> str:
    """Visit `index` by the one regular visitor (the same person every time)."""
    text = robot.visit(index)
    text = re.sub(r"human_visitor_\d+", f"human_{REGULAR}", text)
    return re.sub(r'"Visitor \d+"', '"Regular Visitor"', text)


def load(url: str, robot: OneRobot, visits: int, others: int) -> None:
    with httpx.Client(base_url=url, timeout=600) as client:
        headers = {"Content-Type": "application/n-triples"}
        assert client.post("/ttl", content=robot.first, headers=headers).status_code == 201
        for start in range(0, visits + others, VISITS_PER_POST):
            body = "".join(
                regular_visit(robot, index) if index < visits else robot.visit(index)
                for index in range(start, min(start + VISITS_PER_POST, visits + others))
            )
            answer = client.post("/ttl", content=body, headers=headers)
            assert answer.status_code == 201, answer.text


def settled(url: str, timeout: float = 3600) -> float:
    began = time.monotonic()
    while time.monotonic() - began < timeout:
        body = httpx.get(f"{url}/healthz/ready", timeout=30).json()
        if "apply_lag" not in body and "reports_lag" not in body:
            return time.monotonic() - began
        time.sleep(0.2)
    raise RuntimeError("the server did not settle")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.people")
    parser.add_argument("--visits", type=int, default=10_000, help="visits of the person erased")
    parser.add_argument("--others", type=int, default=8_000, help="visits of people who come once")
    args = parser.parse_args(argv)
    robot = one_robot()
    with tempfile.TemporaryDirectory(prefix="segb-bench-people-") as root:
        data_dir = Path(root) / "data"
        with segb_server("oxigraph", data_dir) as server:
            began = time.monotonic()
            load(server.url, robot, args.visits, args.others)
            settled(server.url)
            loaded = time.monotonic() - began
            count = httpx.post(f"{server.url}/sparql", data={"query": "SELECT (COUNT(*) AS ?n) { ?s ?p ?o }"},
                               timeout=600).json()["results"]["bindings"][0]["n"]["value"]  # fmt: skip
            ingest = Ingest(server.url, robot)
            poster = threading.Thread(target=ingest.run, args=(10_000_000,), daemon=True)
            poster.start()
            time.sleep(3)
            before = len(ingest.latencies)
            human = f"https://example.org/segb/robots/ari/v1/human_{REGULAR}"
            began = time.monotonic()
            erased = httpx.post(f"{server.url}/humans/erase", json={"iri": human, "reason": "bench"}, timeout=3600)
            answered = time.monotonic() - began
            during = (ingest.latencies[before:], ingest.statuses[before:])
            views = settled(server.url)
            ingest.stop()
            poster.join(timeout=120)
            assert erased.status_code == 200, erased.text
            erasure = erased.json()
            hour = {"robot": "https://example.org/segb/robots/ari/v1/robot_ari",
                    "since": T0.isoformat(), "until": T0.replace(hour=T0.hour + 1).isoformat()}  # fmt: skip
            key = httpx.get(f"{server.url}/.well-known/segb-evidence-key").content
            began = time.monotonic()
            bundle = httpx.get(f"{server.url}/evidence", params=hour, timeout=3600)
            exported = time.monotonic() - began
            assert bundle.status_code == 200, bundle.text
            path = Path(root) / "bundle.zip"
            path.write_bytes(bundle.content)
            began = time.monotonic()
            report = verify_bundle(path, key)
            verified = time.monotonic() - began
    latencies, statuses = during
    print(f"Machine: {machine()}\n")
    print(f"Store: {int(count):,} triples ({args.visits:,} visits of the person erased, {args.others:,} others); "
          f"loaded in {loaded:.0f} s\n")  # fmt: skip
    print("| erasure | value |\n|---|---|")
    print(f"| answered after | {answered:.1f} s |")
    for step, seconds in erasure["seconds"].items():
        print(f"| — {step} | {seconds:.2f} s |")
    print(f"| triples removed | {erasure['triples_removed']:,} from {erasure['receipts_redacted']} posts |")
    print(f"| views rebuilt before the answer | {erasure['views_rebuilt']} (then settled in {views:.1f} s) |")
    ok = [value for value, status in zip(latencies, statuses, strict=True) if status == 201]
    others = ", ".join(
        f"{statuses.count(code)} answered {code or 'no answer'}" for code in sorted(set(statuses) - {201})
    )
    print(f"| posts meanwhile (one every 0.1 s) | {len(statuses)}: {statuses.count(201)} answered 201"
          f"{', ' + others if others else ''} |")  # fmt: skip
    if ok:
        print(f"| their latency p50 / p95 / max | {percentile(ok, 50):.0f} / {percentile(ok, 95):.0f} / "
              f"{max(ok):.0f} ms |")  # fmt: skip
    print("\n| evidence export (one hour of one robot) | value |\n|---|---|")
    visits_in_hour = 3600 // SECONDS_PER_VISIT
    print(f"| window | {visits_in_hour} visits |")
    print(f"| export | {exported:.1f} s, {len(bundle.content) / 1e6:.1f} MB |")
    print(f"| offline check | {verified:.1f} s, {'verified' if report.valid else report.problems[:3]} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
