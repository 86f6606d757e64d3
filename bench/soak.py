"""The soak: one robot that never stops logging, posted to as fast as the server answers, while an auditor reads.

    python -m bench.soak                       # 15 minutes, embedded store, 4 client threads
    python -m bench.soak --store virtuoso      # against a Virtuoso this command starts, 2 API workers (as compose)
    python -m bench.soak --server-log run.log  # keep the server's log (--server-log-level DEBUG: each views' batch)
    python -m bench.soak --minutes 2           # a shorter run
    python -m bench.soak --compare             # views off, then on, in one run: the ratios the targets name
    python -m bench.soak --disk-breakdown      # and where the views' files spend their bytes (bench/views_disk.py)

Every post is one visit to the same robot (bench/one_robot.py: about 56 triples, a new visitor each time), so
the robot's node gains children with every post for the whole run; the clock starts once the server's views are
built. With several API workers each post opens a connection of its own, as the PyPI client's `requests.post`
does, so the kernel spreads them over the workers. Meanwhile an auditor reads the
conversations, participants, emotion-timeline and ml-usage reports and the graph every 2 s, a probe reads
`/healthz/ready` every 0.5 s (how far the views are behind, in entries and seconds), and the server's resident
memory is sampled every 5 s. When the posting ends, the command waits for the views to catch up, checks that
every acknowledged post's triples are in the store, and prints the figures (markdown) with the sizes on disk of
the store and of the views' files.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import itertools
import json
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import httpx

from bench import views_disk
from bench.client import BenchError, Client
from bench.measure import Latency, cpu_seconds, machine, percentile
from bench.one_robot import OneRobot, one_robot
from bench.server import ServerProcess, segb_server
from segb_server.backend.services.container import VIEW_FILES

AUDITOR_PAGES = (
    "/reports/conversations?limit=50",
    "/reports/participants?limit=50",
    "/reports/emotion-timeline?limit=50",
    "/reports/ml-usage?limit=50",
    "/graph",
)
TARGETS = {"posts/s": 200.0, "lag p99 s": 2.0, "caught up s": 5.0, "page p50 ms": 50.0, "page p95 ms": 150.0}
# On Virtuoso (the compose default) the targets ask for fewer posts a second and allow the reports further behind.
VIRTUOSO_TARGETS = {**TARGETS, "posts/s": 100.0, "lag p99 s": 5.0}


@dataclass
class Posting:
    """What the client threads did."""

    acknowledged: int = 0
    errors: list[str] = field(default_factory=list)
    latencies: list[float] = field(default_factory=list)
    seconds: float = 0.0
    next_visit: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)

    def take(self) -> int:
        with self.lock:
            index, self.next_visit = self.next_visit, self.next_visit + 1
            return index


@dataclass
class Samples:
    """What the auditor, the readiness probe and the memory sampler saw."""

    pages: dict[str, list[float]] = field(default_factory=dict)
    page_failures: list[str] = field(default_factory=list)
    lag_seconds: list[float] = field(default_factory=list)
    lag_entries: list[int] = field(default_factory=list)
    rss_mib: list[tuple[float, float]] = field(default_factory=list)  # (seconds since start, MiB)
    rss_by_posts: list[tuple[int, float]] = field(default_factory=list)  # (posts acknowledged then, MiB)
    store_mib: list[tuple[float, float]] = field(default_factory=list)
    # (posts acknowledged then, the CPU seconds the server's processes had used): what a post costs as it goes on
    cpu_by_posts: list[tuple[int, float]] = field(default_factory=list)


@dataclass(frozen=True)
class SoakFigures:
    store: str
    minutes: float
    clients: int
    keep_views: bool
    workers: int
    posting: Posting
    samples: Samples
    caught_up_seconds: float | None
    stored_triples: int
    expected_triples: int
    disk_mib: dict[str, float]
    disk_breakdown: list[str] = field(default_factory=list)  # bench/views_disk.py's tables, when asked

    @property
    def rate(self) -> float:
        return self.posting.acknowledged / self.posting.seconds if self.posting.seconds else 0.0

    @property
    def targets(self) -> dict[str, float]:
        return VIRTUOSO_TARGETS if self.store == "virtuoso" else TARGETS

    def markdown(self) -> str:
        views = "" if self.keep_views else ", views off (KEEP_VIEWS=false)"
        workers = f", {self.workers} API workers" if self.workers > 1 else ""
        lines = [
            f"Soak: {self.store} store, one robot, {self.clients} client threads, {self.minutes:g} minutes{workers}"
            f"{views} (`python -m bench.soak --store {self.store} --minutes {self.minutes:g} "
            f"--workers {self.workers}`).",
            "",
            "| figure | measured | target |",
            "|---|--:|--:|",
            f"| posts acknowledged | {self.posting.acknowledged:,} ({self.rate:.0f} posts/s) | "
            f"≥ {self.targets['posts/s']:.0f} posts/s |",
        ]
        post = Latency.of(self.posting.latencies) if self.posting.latencies else None
        if post is not None:
            lines.append(f"| post latency p50 / p99 ms | {post.p50:.1f} / {post.p99:.1f} | |")
        lag = self.samples.lag_seconds or [0.0]
        lines += [
            f"| reports_lag during the run p50 / p99 / max s | {percentile(lag, 50):.2f} / {percentile(lag, 99):.2f} /"
            f" {max(lag):.2f} | p99 ≤ {self.targets['lag p99 s']:.0f} s |",
            f"| views caught up after the writes stopped | "
            f"{'never' if self.caught_up_seconds is None else f'{self.caught_up_seconds:.2f} s'} | "
            f"≤ {self.targets['caught up s']:.0f} s |",
            f"| errors (posts / pages) | {len(self.posting.errors)} / {len(self.samples.page_failures)} | 0 |",
            f"| lost (triples acknowledged, not stored) | {max(0, self.expected_triples - self.stored_triples):,} of "
            f"{self.expected_triples:,} | 0 |",
        ]
        for page, seconds in self.samples.pages.items():
            figures = Latency.of(seconds)
            lines.append(f"| auditor `{page}` p50 / p95 ms (n={figures.n}) | {figures.p50:.1f} / {figures.p95:.1f} | "
                         f"≤ {self.targets['page p50 ms']:.0f} / {self.targets['page p95 ms']:.0f} |")  # fmt: skip
        lines += self._memory_lines()
        lines += self._cpu_lines()
        disk = self.disk_mib
        views = sum(size for name, size in disk.items() if name != "store")
        lines.append(
            f"| disk: store / views ({', '.join(f'{n} {s:.0f}' for n, s in disk.items() if n != 'store')}) MiB | "
            f"{disk.get('store', 0):.0f} / {views:.0f} ({views / disk['store'] if disk.get('store') else 0:.2f}x) | "
            "views ≤ 0.5x |"
        )
        return "\n".join(lines)

    def _memory_lines(self) -> list[str]:
        rss = self.samples.rss_mib
        if not rss:
            return []
        end = rss[-1][0]
        last = [(at, mib) for at, mib in rss if at >= end - 300]
        store = [(at, mib) for at, mib in self.samples.store_mib if at >= end - 300]
        lines = [f"| server RSS start / end / max MiB | {rss[0][1]:.0f} / {rss[-1][1]:.0f} / "
                 f"{max(m for _, m in rss):.0f} | |"]  # fmt: skip
        if len(last) > 1 and len(store) > 1:
            lines.append(
                f"| last 5 minutes: RSS grew / store on disk grew MiB | {last[-1][1] - last[0][1]:+.0f} / "
                f"{store[-1][1] - store[0][1]:+.0f} | RSS ≤ what the store explains |"
            )
        return lines

    def _cpu_lines(self) -> list[str]:
        """The server's CPU a post over the run's first and last thirds: whether a post costs more as the
        robot's history grows."""
        cpu = self.samples.cpu_by_posts
        third = len(cpu) // 3
        first, last = ms_a_post(cpu[: third + 1]), ms_a_post(cpu[-third - 1 :])
        if not third or first is None or last is None:
            return []
        return [f"| server CPU ms a post (its processes'), first / last third of the run | {first:.1f} / {last:.1f} "
                f"({last / first:.2f}x) | |"]  # fmt: skip


def ms_a_post(samples: list[tuple[int, float]]) -> float | None:
    """CPU milliseconds a post between the first and the last of `samples` ((posts, CPU seconds) pairs); None
    when no post was acknowledged between them."""
    if len(samples) < 2 or samples[-1][0] <= samples[0][0]:
        return None
    return (samples[-1][1] - samples[0][1]) * 1000 / (samples[-1][0] - samples[0][0])


def soak(
    store: str,
    minutes: float,
    clients: int,
    auditor_interval: float,
    root: Path,
    keep_views: bool = True,
    workers: int = 1,
    log_level: str = "WARNING",
    server_log: Path | None = None,
    disk_breakdown: bool = False,
) -> SoakFigures:
    robot = one_robot()
    with _server(store, root, keep_views, workers, log_level) as (server, data_dir):
        with Client(server.url) as client:
            client.publish(robot.first)
        # The run measures a server in its stride: every view built (the audit rules' SHACL check among them)
        # before the clock starts, as after a deployment's first start.
        if caught_up(server.url, timeout=600) is None:
            raise BenchError("the views were not built within 10 minutes of the start")
        posting, samples = Posting(), Samples()
        stop = threading.Event()
        started = time.monotonic()
        watchers = [
            threading.Thread(target=_audit, args=(server.url, samples, stop, auditor_interval), daemon=True),
            threading.Thread(target=_probe, args=(server.url, samples, stop), daemon=True),
            threading.Thread(
                target=_sample_memory,
                args=(server, _store_files(store, data_dir), samples, stop, started, posting),
                daemon=True,
            ),
        ]
        posters = [
            threading.Thread(target=post_visits, args=(server.url, robot, posting, stop, workers > 1), daemon=True)
            for _ in range(clients)
        ]
        for thread in [*watchers, *posters]:
            thread.start()
        _progress(posting, samples, stop, started, minutes * 60)
        stop.set()
        for thread in posters:
            thread.join()
        posting.seconds = time.monotonic() - started
        drained = caught_up(server.url)
        for thread in watchers:
            thread.join()
        stored = _stored_triples(server.url)
        expected = len(robot.first.splitlines()) + posting.acknowledged * len(robot.visit(0).splitlines())
        disk = _disk(store, data_dir)
        breakdown = views_disk.report(data_dir, top=8) if disk_breakdown else []
        if server_log is not None:
            server_log.write_text(server.log_text())
    return SoakFigures(
        store, minutes, clients, keep_views, workers, posting, samples, drained, stored, expected, disk, breakdown
    )


def compared(off: SoakFigures, on: SoakFigures) -> str:
    """The ratios the targets name: posts/s with every view kept against none (≥ 0.8), and the server's memory
    at the same number of triples (≤ 1.2): the run with views off passes the other's final count on its way
    (it posts faster), and its memory then is read off its samples."""
    rss_off, rss_on = off.samples.rss_mib[-1][1], on.samples.rss_mib[-1][1]
    same = rss_when(off.samples.rss_by_posts, on.posting.acknowledged)
    return "\n".join([
        "| views off / on | off | on | on ÷ off | target |",
        "|---|--:|--:|--:|--:|",
        f"| posts/s | {off.rate:.0f} | {on.rate:.0f} | {on.rate / off.rate if off.rate else 0:.2f} | ≥ 0.8 |",
        f"| triples stored | {off.stored_triples:,} | {on.stored_triples:,} | | |",
        f"| RSS at the end MiB | {rss_off:.0f} | {rss_on:.0f} | | |",
        f"| RSS at {on.posting.acknowledged:,} posts MiB | {_mib(same)} | {rss_on:.0f} | "
        f"{rss_on / same if same else 0:.2f} | ≤ 1.2 |",
    ])  # fmt: skip


def rss_when(samples: list[tuple[int, float]], posts: int) -> float | None:
    """The memory when `posts` posts were acknowledged, between the samples around it; None when the run never
    got there."""
    for (before, low), (after, high) in itertools.pairwise(samples):
        if before <= posts <= after:
            return low if after == before else low + (high - low) * (posts - before) / (after - before)
    return None


def _mib(value: float | None) -> str:
    return "not reached" if value is None else f"{value:.0f}"


@contextlib.contextmanager
def _server(
    store: str, root: Path, keep_views: bool, workers: int, log_level: str
) -> Iterator[tuple[ServerProcess, Path]]:
    data_dir = root / "data"
    data_dir.mkdir()
    env = {"LOGGING_LEVEL": log_level, "KEEP_VIEWS": "true" if keep_views else "false", "API_WORKERS": str(workers)}
    if store == "virtuoso":
        from tests.support.virtuoso import VirtuosoProcess

        (root / "virtuoso").mkdir()
        virtuoso = VirtuosoProcess(root / "virtuoso")
        virtuoso.start()
        try:
            env |= {"VIRTUOSO_ENDPOINT": virtuoso.endpoint, "VIRTUOSO_PASSWORD": virtuoso.password,
                    "VIRTUOSO_USER": virtuoso.user}  # fmt: skip
            with segb_server("virtuoso", data_dir, env) as server:
                yield server, data_dir
        finally:
            virtuoso.stop()
    else:
        with segb_server("oxigraph", data_dir, env) as server:
            yield server, data_dir


def post_visits(url: str, robot: OneRobot, posting: Posting, stop: threading.Event, connection_per_post: bool) -> None:
    """Posts visits until stopped. With several API workers, a new connection for each post, as the PyPI client
    makes: four kept-alive connections would all be served by whichever workers accepted them first."""
    with Client(url, timeout=120, connection_per_request=connection_per_post) as client:
        while not stop.is_set():
            payload = robot.visit(posting.take())
            begin = time.perf_counter()
            try:
                client.publish(payload)
            except (BenchError, OSError) as error:
                with posting.lock:
                    posting.errors.append(str(error)[:200])
                time.sleep(0.1)
                client.close()
                client = Client(url, timeout=120, connection_per_request=connection_per_post)
                continue
            with posting.lock:
                posting.acknowledged += 1
                posting.latencies.append(time.perf_counter() - begin)


def _audit(url: str, samples: Samples, stop: threading.Event, interval: float) -> None:
    with httpx.Client(base_url=url, timeout=60) as client:
        while not stop.wait(interval):
            for page in AUDITOR_PAGES:
                begin = time.perf_counter()
                try:
                    answer = client.get(page)
                except httpx.HTTPError as error:
                    samples.page_failures.append(f"{page}: {error}")
                    continue
                if answer.status_code != 200:
                    samples.page_failures.append(f"{page}: {answer.status_code} {answer.text[:200]}")
                    continue
                samples.pages.setdefault(page, []).append(time.perf_counter() - begin)


def _probe(url: str, samples: Samples, stop: threading.Event) -> None:
    with httpx.Client(base_url=url, timeout=30) as client:
        while not stop.wait(0.5):
            with contextlib.suppress(httpx.HTTPError, ValueError):
                lag = client.get("/healthz/ready").json().get("reports_lag") or {}
                samples.lag_entries.append(int(lag.get("entries", 0)))
                samples.lag_seconds.append(float(lag.get("seconds", 0.0)))


def _sample_memory(
    server: ServerProcess, store_files: Path, samples: Samples, stop: threading.Event, t0: float, posting: Posting
) -> None:
    while not stop.is_set():
        processes = _server_processes(server.pid)
        rss, cpu = _rss_mib(processes), _cpu_seconds(processes)
        now = time.monotonic() - t0
        if rss is not None:
            samples.rss_mib.append((now, rss))
            samples.rss_by_posts.append((posting.acknowledged, rss))
        if cpu is not None:
            samples.cpu_by_posts.append((posting.acknowledged, cpu))
        samples.store_mib.append((now, _size_mib(store_files)))
        stop.wait(5)


def _progress(posting: Posting, samples: Samples, stop: threading.Event, started: float, seconds: float) -> None:
    since = len(samples.cpu_by_posts) - 1  # the CPU sample the next line's cost a post is counted from
    while (elapsed := time.monotonic() - started) < seconds:
        time.sleep(min(30.0, seconds - elapsed))
        lag = samples.lag_seconds[-1] if samples.lag_seconds else 0.0
        rss = samples.rss_mib[-1][1] if samples.rss_mib else 0.0
        cost = ms_a_post(samples.cpu_by_posts[max(0, since) :])
        since = len(samples.cpu_by_posts) - 1
        print(f"  {time.monotonic() - started:5.0f} s: {posting.acknowledged:,} posts, reports_lag {lag:.2f} s, "
              f"RSS {rss:.0f} MiB, server CPU {'-' if cost is None else f'{cost:.1f}'} ms a post, "
              f"errors {len(posting.errors)}", file=sys.stderr, flush=True)  # fmt: skip


def caught_up(url: str, timeout: float = 1800) -> float | None:
    begin = time.monotonic()
    with httpx.Client(base_url=url, timeout=30) as client:
        while time.monotonic() - begin < timeout:
            body = client.get("/healthz/ready").json()
            if not {"reports_lag", "apply_lag", "views_building"} & set(body):
                return time.monotonic() - begin
            time.sleep(0.05)
    return None


def _stored_triples(url: str) -> int:
    answer = httpx.post(url + "/sparql", data={"query": "SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }"},
                        headers={"Accept": "application/sparql-results+json"}, timeout=600)  # fmt: skip
    answer.raise_for_status()
    return int(answer.json()["results"]["bindings"][0]["n"]["value"])


def _store_files(store: str, data_dir: Path) -> Path:
    """Where the store keeps its data: the embedded store's folder, or the Virtuoso's (its database and
    transaction log, beside the server's data directory: `_server`)."""
    return data_dir.parent / "virtuoso" if store == "virtuoso" else data_dir / "oxigraph"


def _disk(store: str, data_dir: Path) -> dict[str, float]:
    sizes = {"store": _size_mib(_store_files(store, data_dir))}
    for name in VIEW_FILES:
        sizes[name] = sum(_size_mib(data_dir / f"{name}{suffix}") for suffix in ("", "-wal"))
    return sizes


def _size_mib(path: Path) -> float:
    if path.is_file():
        return path.stat().st_size / 2**20
    if path.is_dir():
        return sum(item.stat().st_size for item in path.rglob("*") if item.is_file()) / 2**20
    return 0.0


def _server_processes(pid: int | None) -> list[int]:
    """The server's process and its children (several API workers, the views' process)."""
    return [] if pid is None else [pid, *_children(pid)]


def _rss_mib(processes: list[int]) -> float | None:
    """The server's resident memory: every one of its processes'."""
    sizes = [_own_rss_mib(process) for process in processes]
    known = [size for size in sizes if size is not None]
    return sum(known) if known else None


def _cpu_seconds(processes: list[int]) -> float | None:
    """The CPU the server's processes have used (those alive now: a worker that ended takes its share along)."""
    used = []
    for process in processes:
        with contextlib.suppress(OSError, ValueError, IndexError):
            used.append(cpu_seconds(process))
    return sum(used) if used else None


def _own_rss_mib(pid: int) -> float | None:
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return None


def _children(pid: int) -> list[int]:
    """Every process under `pid` (uvicorn's supervisor starts the workers, multiprocessing a resource tracker)."""
    parents: dict[int, int] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, ValueError, IndexError):
            # the command name (second field) may hold spaces: the parent is the second field after its ')'
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
    found, frontier = [], [pid]
    while frontier:
        parent = frontier.pop()
        children = [child for child, of in parents.items() if of == parent]
        found += children
        frontier += children
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.soak", description=__doc__.split("\n\n")[0])
    parser.add_argument("--store", choices=("oxigraph", "virtuoso"), default="oxigraph")
    parser.add_argument("--minutes", type=float, default=15.0)
    parser.add_argument("--clients", type=int, default=4)
    parser.add_argument(
        "--workers",
        type=int,
        help="API processes (API_WORKERS); by default 1 on the embedded store (it allows no other) and, as "
        "docker-compose.yaml runs it, 2 on Virtuoso",
    )
    parser.add_argument("--auditor-interval", type=float, default=2.0)
    parser.add_argument("--json", type=Path, help="also write the figures as JSON to this file")
    parser.add_argument("--server-log", type=Path, help="keep the server's log (of the run with views on) in this file")
    parser.add_argument(
        "--server-log-level",
        default="WARNING",
        help="the server's LOGGING_LEVEL (DEBUG: each views' batch with its slowest views; it slows the server)",
    )
    parser.add_argument("--compare", action="store_true", help="run with views off first, then on: the ratios")
    parser.add_argument("--views-off", action="store_true", help="only the run with the views off (KEEP_VIEWS=false)")
    parser.add_argument(
        "--disk-breakdown", action="store_true", help="print where the views' files spend their bytes (views on)"
    )
    args = parser.parse_args(argv)
    workers = args.workers or (2 if args.store == "virtuoso" else 1)
    gc.disable()  # the bench's own collections would be counted in whichever request was in flight
    off = None
    if args.compare:
        with tempfile.TemporaryDirectory(prefix="segb-soak-") as root:
            off = soak(args.store, args.minutes, args.clients, args.auditor_interval, Path(root), False, workers,
                       args.server_log_level)  # fmt: skip
        print(off.markdown() + "\n")
    with tempfile.TemporaryDirectory(prefix="segb-soak-") as root:
        figures = soak(
            args.store, args.minutes, args.clients, args.auditor_interval, Path(root), not args.views_off, workers,
            args.server_log_level, args.server_log, args.disk_breakdown,
        )  # fmt: skip
    print(figures.markdown())
    if figures.disk_breakdown:
        print("\n" + "\n".join(figures.disk_breakdown))
    if off is not None:
        print("\n" + compared(off, figures))
    print("\nmachine: " + "; ".join(f"{k} {v}" for k, v in machine().items()))
    if args.json:
        args.json.write_text(json.dumps({"markdown": figures.markdown(), "rate": figures.rate}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
