"""The investigator's timeline under live ingest: `GET /timeline` for a one-hour window of one robot, on a store
loaded with `segb import`, while another robot publishes 10 posts a second; how soon a post's events reach an open
timeline stream; what keeping the timeline costs (its views' build, the posts' latency and the views' lag against a
server keeping only one of its kinds). Writes its own section of docs/performance.md.

    python -m bench.timeline                     # 1,000,000 triples, the embedded store (about 15 minutes here)
    python -m bench.timeline --size 100000 --repeats 5 --output /tmp/perf.md   # a smoke run
"""

from __future__ import annotations

import argparse
import gc
import json
import re
import shutil
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

import httpx

from bench.__main__ import LIVE_RATE, code_version, count_lines, segb_import, write_dataset
from bench.live import Background, publishing
from bench.measure import Latency, machine, percentile
from bench.probes import LagFigures, ReadinessProbe, wait_caught_up
from bench.server import ROOT, ServerProcess, segb_server
from tests.support.robot_posts import live_posts, robot_of

SECTION = "timeline"
BUILT = re.compile(r"view timeline/(\S+) built in ([\d.]+) s")
PAGE = 1000  # events a page, the API's default
NONE = "-"  # a figure not measured


@dataclass
class Run:
    """One server: what it built, what its pages took, and the posts and views beside them."""

    label: str
    built_seconds: float | None = None  # start to every view built
    kinds_built: dict[str, float] = field(default_factory=dict)
    pages: dict[str, Latency] = field(default_factory=dict)
    events: dict[str, int] = field(default_factory=dict)
    document: tuple[float, int] | None = None  # the window as one HTML file: seconds, bytes
    stream: Latency | None = None  # a post's 201 to its message's row on the live stream
    posts: Latency | None = None
    lag: LagFigures | None = None
    rows_file_mib: float | None = None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.timeline", description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=1_000_000, help="triples in the store")
    parser.add_argument("--repeats", type=int, default=30, help="times each request is measured")
    parser.add_argument("--output", type=Path, default=Path(tempfile.gettempdir()) / "segb-bench.md")
    args = parser.parse_args(argv)
    started, load_at_start, code = time.perf_counter(), machine(), code_version()
    gc.disable()  # as the bench does: the client's collections would count in whichever request was in flight
    with tempfile.TemporaryDirectory(prefix="segb-bench-timeline-") as scratch:
        root = Path(scratch)
        files = write_dataset(root, args.size)
        triples = count_lines(files)
        load_seconds = segb_import("oxigraph", root / "data", files)
        runs = [measure(root / "data", "every kind kept", {}, args.repeats, "live")]
        runs.append(measure(root / "data", "only states kept", one_kind(root), args.repeats, "live2"))
    gc.enable()
    wall = time.perf_counter() - started
    text = section(triples, load_seconds, runs, wall, {**load_at_start, "code": code}, argv or sys.argv[1:])
    write_section(args.output, text)
    print(text)
    return 0


def one_kind(root: Path) -> dict[str, str]:
    """A copy of the queries whose timeline keeps robot states only: the others' upkeep, by difference."""
    folder = root / "sparql-states-only"
    shutil.copytree(ROOT / "sparql", folder)
    for query in (folder / "timeline").glob("*.rq"):
        if query.name != "state.rq":
            query.unlink()
    return {"SPARQL_DIR": str(folder)}


def measure(data_dir: Path, label: str, env: dict[str, str], repeats: int, live_robot: str) -> Run:
    run = Run(label)
    posts = live_posts(3_000, live_robot)
    with segb_server("oxigraph", data_dir, env) as server:
        run.built_seconds = wait_built(server)
        run.kinds_built = {match[1]: float(match[2]) for match in BUILT.finditer(server.log_text())}
        with httpx.Client(base_url=server.url, timeout=600) as client:
            robot, window = sample_window(client)
            background = Background()
            with (
                ReadinessProbe(server.url, interval=0.2) as probe,
                publishing(server.url, posts, LIVE_RATE, background),
            ):
                heard = stream_arrivals(server.url, robot_of(posts[0].payload), background, seconds=20)
                if label == "every kind kept":
                    measure_pages(client, robot, window, repeats, run)
                else:  # only the posts and the views beside them: its timeline lacks most kinds
                    time.sleep(30)
            run.lag = LagFigures.of(probe.samples, wait_caught_up(server.url))
        run.stream = Latency.of(heard) if heard else None
        run.posts = Latency.of(background.latencies) if background.latencies else None
    rows = data_dir / "timeline.sqlite3"
    if not env:  # a later server on the same data directory keeps fewer kinds in the same (unshrunk) file
        run.rows_file_mib = rows.stat().st_size / 2**20 if rows.exists() else None
    return run


def wait_built(server: ServerProcess, timeout: float = 3600) -> float | None:
    """Start to every view built: `/graph` answers once every view is (503 until then)."""
    with httpx.Client(base_url=server.url, timeout=600) as client:
        while time.monotonic() - server.started < timeout:
            if client.get("/graph", params={"limit": 1}).status_code == 200:
                return time.monotonic() - server.started
            time.sleep(0.5)
    return None


def sample_window(client: httpx.Client) -> tuple[str, dict[str, str]]:
    """The first robot the participants report names, and the hour from its first event."""
    robot = client.get("/reports/participants", params={"limit": 1}).json()["rows"][0]["robot"]
    first = client.get("/timeline", params={"robot": robot, "limit": 1}).json()["rows"][0]["time"]
    since = datetime.fromisoformat(first.replace("Z", "+00:00")).astimezone(UTC)
    return robot, {"since": since.isoformat(), "until": (since + timedelta(hours=1)).isoformat()}


def measure_pages(client: httpx.Client, robot: str, window: dict[str, str], repeats: int, run: Run) -> None:
    params = {"robot": robot, **window, "limit": PAGE}
    first, following, whole, document = [], [], [], []
    for _ in range(repeats):
        begin = time.perf_counter()
        answer = client.get("/timeline", params=params).json()
        first.append(time.perf_counter() - begin)
        events, cursor = len(answer["rows"]), answer["next"]
        if cursor:
            begin = time.perf_counter()
            client.get("/timeline", params={**params, "after": cursor}).raise_for_status()
            following.append(time.perf_counter() - begin)
        begin = time.perf_counter()
        while cursor:  # the rest of the window, as the page fetches it
            answer = client.get("/timeline", params={**params, "after": cursor}).json()
            events, cursor = events + len(answer["rows"]), answer["next"]
        whole.append(time.perf_counter() - begin + first[-1])
        run.events["window"] = events
    for _ in range(max(1, repeats // 5)):
        begin = time.perf_counter()
        html = client.get("/timeline", params={"robot": robot, **window, "format": "html"})
        document.append(time.perf_counter() - begin)
        run.document = (percentile(document, 50), len(html.content))
    run.pages["first page (1,000 events)"] = Latency.of(first)
    if following:
        run.pages["the page after it"] = Latency.of(following)
    run.pages["the whole hour, page by page"] = Latency.of(whole)


def stream_arrivals(url: str, robot: str, background: Background, seconds: float) -> list[float]:
    """For `seconds`, the live robot's timeline stream as an open page follows it: for each post with a message,
    from its 201 to the stream's event holding that message's row."""
    arrivals: dict[str, float] = {}
    done = threading.Event()

    def read() -> None:
        timeout = httpx.Timeout(60, read=None)
        with httpx.Client(base_url=url, timeout=timeout) as client:
            try:
                with client.stream("GET", "/timeline/stream", params={"robot": robot, "kind": "message"}) as stream:
                    for line in stream.iter_lines():
                        if done.is_set():
                            return
                        if line.startswith("data:"):
                            for row in json.loads(line.removeprefix("data:"))["rows"]:
                                arrivals.setdefault(row["iri"], time.time())
            except httpx.HTTPError:
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    opened = time.time()
    time.sleep(seconds)
    done.set()
    waits = []
    for messages, answered in list(background.answered):
        if answered > opened + 1 and all(message in arrivals for message in messages):
            waits.append(max(arrivals[message] for message in messages) - answered)
    return waits


def section(
    triples: int, load_seconds: float, runs: list[Run], wall: float, at_start: dict[str, str], argv: list[str]
) -> str:
    every = runs[0]
    command = " ".join(["python -m bench.timeline", *argv])
    lines = [
        f"<!-- section: {SECTION} -->",
        "### 10. The investigator's timeline under live ingest",
        "",
        f"Measured {datetime.now(UTC):%Y-%m-%d} with `{command}` ({wall:.0f} s), {at_start['code']}, on the embedded"
        f" store loaded with `segb import` ({triples:,} triples, {load_seconds:.0f} s): the reports' dataset of"
        f" section 5. Machine: {at_start['cpu']}, load average at start {at_start['load average at start']}. While"
        f" the timeline is measured another robot publishes {LIVE_RATE:g} posts a second. The window is one robot's"
        f" first hour ({every.events.get('window', 0):,} events); each request is repeated.",
        "",
        "| request | n | p50 ms | p95 ms | max ms |",
        "|---|--:|--:|--:|--:|",
    ]
    timed = dict(every.pages)
    if every.stream:
        timed["a post's 201 to its message on `/timeline/stream`"] = every.stream
    lines += [f"| {name} | {t.n} | {t.p50:.1f} | {t.p95:.1f} | {t.max:.1f} |" for name, t in timed.items()]
    if every.document:
        seconds, size = every.document
        name = f"the hour as one HTML file ({size / 1024:.0f} KiB), p50"
        lines.append(f"| {name} | {NONE} | {seconds * 1000:.1f} | {NONE} | {NONE} |")
    lines += [
        "",
        "**What keeping it costs**: the same store and posts, and a second server keeping only the states kind.",
        "",
        "| server | every view built s | timeline rows MiB | posts p50 / p95 ms | views behind at most, entries"
        " | views caught up after the posts, s |",
        "|---|--:|--:|--:|--:|--:|",
    ]
    lines += [_cost_row(run) for run in runs]
    kinds = sorted(every.kinds_built.items(), key=lambda kind: -kind[1])
    lines += ["", f"Each kind's build, s: {', '.join(f'{kind} {seconds:.1f}' for kind, seconds in kinds)}."]
    return "\n".join([*lines, f"<!-- /section: {SECTION} -->"])


def _cost_row(run: Run) -> str:
    posts = f"{run.posts.p50:.1f} / {run.posts.p95:.1f}" if run.posts else NONE
    behind = str(run.lag.max_reports_entries) if run.lag else NONE
    drained = run.lag.drain.reports_seconds if run.lag else None
    caught_up = f"{drained:.1f}" if drained is not None else NONE
    built = f"{run.built_seconds:.0f}" if run.built_seconds else NONE
    size = f"{run.rows_file_mib:.0f}" if run.rows_file_mib else NONE
    return f"| {run.label} | {built} | {size} | {posts} | {behind} | {caught_up} |"


def write_section(path: Path, text: str) -> None:
    """This bench's section of the page, replaced where it is or added at the end; the rest left as it is."""
    old = path.read_text(encoding="utf-8") if path.exists() else "# Performance\n"
    marked = re.compile(rf"<!-- section: {SECTION} -->.*?<!-- /section: {SECTION} -->", re.S)
    new = marked.sub(lambda _: text, old) if marked.search(old) else old.rstrip("\n") + "\n\n" + text + "\n"
    path.write_text(new, encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
