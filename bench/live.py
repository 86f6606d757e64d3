"""Reports under live ingest: a loaded store, one robot publishing at a steady rate in the background, and every
report's pages, the graph views and an explanation measured meanwhile; plus how long a post's rows take to
show in its report, and how long the reports' rows took to build when the server started."""

from __future__ import annotations

import json
import queue
import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

import httpx
from tqdm import tqdm

from bench.browser import InPage, watch_conversations
from bench.client import BenchError, Client
from bench.crosscheck import rows_of_query
from bench.measure import Latency
from bench.probes import LagFigures, ReadinessProbe, wait_caught_up
from bench.server import ServerProcess, ui_server
from tests.support.robot_posts import LivePost, robot_of

POLL_SECONDS = 0.02
GIVE_UP_SECONDS = 60.0
KEYS = re.compile(r"report reports/(\S+) built: (\d+) keys")
BUILT = re.compile(r"view reports/(\S+) built in ([\d.]+) s")
THRESHOLD = "0.9"
VIEW_REPEATS = 20  # each graph view and the explanation, repeated (as many as a report page)
GRAPH_VIEW = "graph"


@dataclass(frozen=True)
class PageFigures:
    """One report with one set of filters: its first page and (when there is one) the page after it."""

    report: str
    variant: str  # "default", or the filters used
    rows: int
    served_from: str
    first: Latency
    next: Latency | None
    failure: str | None = None  # what the server answered when it did not answer 200
    query_rows: int | None = None  # for an empty filtered page: the rows of the report's query, same filters


@dataclass
class Background:
    """The robot publishing during the measurements."""

    posts: int = 0
    errors: int = 0
    seconds: float = 0.0
    latencies: list[float] = field(default_factory=list)
    visible: list[float] = field(default_factory=list)  # 201 to the post's messages in the conversations report
    not_visible: int = 0
    # The posts with messages as they were answered: (their message IRIs, `time.time()` at the 201).
    answered: list[tuple[tuple[str, ...], float]] = field(default_factory=list)

    @property
    def rate(self) -> float:
        return self.posts / self.seconds if self.seconds else 0.0


@dataclass(frozen=True)
class LiveReports:
    triples: int
    load_seconds: float
    ready_seconds: float  # process start to /healthz/ready answering 200
    rows_seconds: float | None  # process start to every report served from its rows (None: not within the wait)
    built: dict[str, tuple[int, float]]  # report -> (keys, seconds), as the server logged the build
    pages: list[PageFigures]
    views: dict[str, Timed]
    background: Background
    lag: LagFigures
    peak_rss_mib: float | None
    in_page: InPage | None = None  # the robot's messages into its conversations open in Chromium


@dataclass(frozen=True)
class Samples:
    """Values the filters are measured with, taken from the data itself."""

    robot: str
    human: str
    since: str
    until: str
    message: str


def live_reports(
    server: ServerProcess,
    triples: int,
    load_seconds: float,
    repeats: int,
    posts: list[LivePost],
    rate: float,
    browser_seconds: float,
) -> LiveReports:
    """`browser_seconds`: how long the robot's conversations are watched in Chromium first (before the pages are
    measured, so the browser's load is not in their figures)."""
    rows_seconds = wait_for_rows(server)
    with httpx.Client(base_url=server.url, timeout=600) as client:
        samples = sample_values(client)
        background = Background()
        robot = robot_of(posts[0].payload)
        with ReadinessProbe(server.url, interval=0.2) as probe, publishing(server.url, posts, rate, background):
            with ui_server(server.url) as ui:
                in_page = watch_conversations(ui.url, robot, background.answered, browser_seconds)
            pages = measure_pages(client, samples, repeats)
            views = measure_views(client, samples, robot, VIEW_REPEATS)
        lag = LagFigures.of(probe.samples, wait_caught_up(server.url))
    return LiveReports(
        triples=triples,
        load_seconds=load_seconds,
        ready_seconds=server.ready_seconds,
        rows_seconds=rows_seconds,
        built=built_reports(server.log_text()),
        pages=pages,
        views=views,
        background=background,
        lag=lag,
        peak_rss_mib=server.peak_rss_mib,
        in_page=in_page,
    )


# --- start-up --------------------------------------------------------------------------------------------


def wait_for_rows(server: ServerProcess, timeout: float = 3600) -> float | None:
    """Seconds from the server's start until every report answers `served_from: rows` and the graph index
    answers `/graph` (built after the reports, by the same thread: until then posts wait for the views)."""
    with httpx.Client(base_url=server.url, timeout=600) as client:
        names = [report["name"] for report in client.get("/reports").json()["reports"]]
        waiting = {*names, GRAPH_VIEW}
        while waiting and time.monotonic() - server.started < timeout:
            for name in sorted(waiting):
                if name == GRAPH_VIEW:
                    built = client.get("/graph", params={"limit": 1}).status_code == 200
                else:
                    built = client.get(f"/reports/{name}", params={"limit": 1}).json().get("served_from") == "rows"
                if built:
                    waiting.discard(name)
            if waiting:
                time.sleep(0.2)
    return None if waiting else time.monotonic() - server.started


def built_reports(log: str) -> dict[str, tuple[int, float]]:
    """Each report's build as the server logged it (`report reports/<name> built: <keys> keys`, then
    `view reports/<name> built in <s> s`)."""
    keys = {match[1]: int(match[2]) for match in KEYS.finditer(log)}
    return {match[1]: (keys.get(match[1], 0), float(match[2])) for match in BUILT.finditer(log)}


def sample_values(client: httpx.Client) -> Samples:
    """A robot and human that met (participants), a one-day window and a message (conversations)."""
    pair = client.get("/reports/participants", params={"limit": 1}).json()["rows"][0]
    message = client.get("/reports/conversations", params={"limit": 1}).json()["rows"][0]
    since = datetime.fromisoformat(message["time"].replace("Z", "+00:00"))
    return Samples(
        robot=pair["robot"],
        human=pair["human"],
        since=since.isoformat(),
        until=(since + timedelta(days=1)).isoformat(),
        message=message["message"],
    )


# --- the measurements --------------------------------------------------------------------------------------


def variants(parameters: list[str], samples: Samples) -> list[tuple[str, dict[str, str]]]:
    """Default parameters, then each filter the report has (since and until together, as a window)."""
    chosen: list[tuple[str, dict[str, str]]] = [("default", {})]
    if "robot" in parameters:
        chosen.append(("robot", {"robot": samples.robot}))
    if "human" in parameters:
        chosen.append(("human", {"human": samples.human}))
    if "since" in parameters and "until" in parameters:
        chosen.append(("since/until (1 day)", {"since": samples.since, "until": samples.until}))
    if "threshold" in parameters:
        chosen.append((f"threshold {THRESHOLD}", {"threshold": THRESHOLD}))
    return chosen


def measure_pages(client: httpx.Client, samples: Samples, repeats: int) -> list[PageFigures]:
    reports = client.get("/reports").json()["reports"]
    work = [
        (report["name"], variant, filters)
        for report in reports
        for variant, filters in variants([p["name"] for p in report["parameters"]], samples)
    ]
    return [
        _one_variant(client, name, variant, filters, repeats)
        for name, variant, filters in tqdm(work, desc="report pages", leave=False)
    ]


def _one_variant(client: httpx.Client, name: str, variant: str, filters: dict[str, str], repeats: int) -> PageFigures:
    first = timed(client, f"/reports/{name}", filters, repeats)
    cursor = first.answer.get("next")
    following = timed(client, f"/reports/{name}", {**filters, "after": cursor}, repeats) if cursor else None
    rows = len(first.answer.get("rows", []))
    # An empty filtered page is checked against the query itself: a figure for a wrong answer is no figure.
    query_rows = rows_of_query(client, name, filters) if filters and not rows and not first.failure else None
    return PageFigures(
        name,
        variant,
        rows,
        first.answer.get("served_from", "?"),
        first.latency,
        following.latency if following else None,
        first.failure or (following.failure if following else None),
        query_rows,
    )


@dataclass(frozen=True)
class Timed:
    """The same request repeated: its latency (failed answers included), the last good answer, and what the
    server answered when it failed (`HTTP 503: …, 3 of 4`)."""

    latency: Latency
    answer: dict[str, Any]
    failure: str | None


def timed(client: httpx.Client, path: str, params: dict[str, str], repeats: int) -> Timed:
    seconds = []
    answer: dict[str, Any] = {}
    failures: list[str] = []
    for _ in range(repeats):
        begin = time.perf_counter()
        response = client.get(path, params=params)
        seconds.append(time.perf_counter() - begin)
        if response.is_success:
            answer = response.json()
            continue
        # Not repeated: a failure is often a timeout of tens of seconds, and one says what it is.
        failures.append(f"HTTP {response.status_code}: {' '.join(response.text[:160].replace('|', '/').split())}")
        break
    failure = f"{failures[0]} (after {len(seconds)} of {repeats} requests)" if failures else None
    return Timed(Latency.of(seconds), answer, failure)


def measure_views(client: httpx.Client, samples: Samples, publishing: str, repeats: int) -> dict[str, Timed]:
    """The graph page's first view, a robot's neighbourhood (one of the loaded robots, and the robot publishing
    meanwhile, whose neighbourhood every post changes), and the explanation of a message."""
    views = {
        "`/graph` (first view, default limit)": ("/graph", {}),
        "`/graph?focus=<robot>&depth=1`": ("/graph", {"focus": samples.robot, "depth": "1"}),
        "`/graph?focus=<the robot publishing>&depth=1`": ("/graph", {"focus": publishing, "depth": "1"}),
        "`/explain?iri=<message>`": ("/explain", {"iri": samples.message}),
    }
    return {label: timed(client, path, params, repeats) for label, (path, params) in views.items()}


# --- the robot in the background ---------------------------------------------------------------------------


@contextmanager
def publishing(url: str, posts: list[LivePost], rate: float, into: Background) -> Iterator[None]:
    """One robot posts `posts` at `rate` a second while the block runs (it stops early when they run out); a
    second thread times each post's messages into the conversations report."""
    stop = threading.Event()
    pending: queue.Queue[tuple[LivePost, float] | None] = queue.Queue()
    robot = robot_of(posts[0].payload)
    with ReportStream(url, "conversations") as heard:
        poster = threading.Thread(target=_post, args=(url, posts, rate, stop, pending, into), daemon=True)
        checker = threading.Thread(target=_check, args=(url, robot, pending, heard, into), daemon=True)
        poster.start()
        checker.start()
        try:
            yield
        finally:
            stop.set()
            poster.join()
            pending.put(None)
            checker.join()


class ReportStream:
    """`with ReportStream(url, report) as heard:` the units the report's live stream names, each with when it was
    first heard of (the server's `/reports/stream`, as the `/reports` page follows it)."""

    def __init__(self, url: str, report: str) -> None:
        self._client = httpx.Client(base_url=url, timeout=httpx.Timeout(60, read=None))
        self._report = report
        self._heard: dict[str, float] = {}
        self._news = threading.Condition()
        self._open = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)

    def __enter__(self) -> ReportStream:
        self._reader.start()
        if not self._open.wait(GIVE_UP_SECONDS):
            raise BenchError("the reports' live stream did not open")
        return self

    def __exit__(self, *exc: object) -> None:
        self._client.close()  # ends the reader's read

    def _read(self) -> None:
        try:
            with self._client.stream("GET", "/reports/stream", params={"report": self._report}) as stream:
                for line in stream.iter_lines():
                    if line.startswith("retry:"):  # sent once the stream's starting point is set
                        self._open.set()
                    elif line.startswith("data:"):
                        units = json.loads(line.removeprefix("data:"))["units"]
                        with self._news:
                            for unit in units:
                                self._heard.setdefault(unit, time.perf_counter())
                            self._news.notify_all()
        except (httpx.HTTPError, RuntimeError):  # closed at the end
            return

    def wait_for(self, units: set[str], timeout: float) -> bool:
        """Whether every one of `units` was heard of within `timeout` seconds."""
        with self._news:
            return self._news.wait_for(lambda: units <= self._heard.keys(), timeout)


def _post(
    url: str,
    posts: list[LivePost],
    rate: float,
    stop: threading.Event,
    pending: queue.Queue[tuple[LivePost, float] | None],
    into: Background,
) -> None:
    with Client(url) as client:
        started = time.perf_counter()
        for index, post in enumerate(posts):
            if stop.wait(max(0.0, started + index / rate - time.perf_counter())):
                break
            begin = time.perf_counter()
            try:
                client.publish(post.payload)
            except (BenchError, OSError):
                into.errors += 1
                continue
            answered = time.perf_counter()
            into.latencies.append(answered - begin)
            into.posts += 1
            if post.messages:
                into.answered.append((post.messages, time.time()))
                pending.put((post, answered))
        into.seconds = time.perf_counter() - started


def _check(
    url: str, robot: str, pending: queue.Queue[tuple[LivePost, float] | None], heard: ReportStream, into: Background
) -> None:
    """Each message post in turn, as a live `/reports` page sees it: once the report's stream names its messages,
    read its robot's conversations since its time (again, until its messages are rows). Checks that fall behind
    are skipped rather than timed late, so no figure includes time spent queued."""
    with httpx.Client(base_url=url, timeout=60) as client:
        while (item := pending.get()) is not None:
            post, answered = item
            if not pending.empty():
                continue  # a later post is waiting: time that one instead
            told = heard.wait_for({f"<{message}>" for message in post.messages}, GIVE_UP_SECONDS)
            seen = _poll(client, robot, post, answered) if told else None
            if seen is None:
                into.not_visible += 1
            else:
                into.visible.append(seen - answered)


def _poll(client: httpx.Client, robot: str, post: LivePost, since: float) -> float | None:
    wanted = set(post.messages)
    while time.perf_counter() - since < GIVE_UP_SECONDS:
        answer = client.get("/reports/conversations", params={"robot": robot, "since": post.since})
        if answer.status_code == 200 and wanted <= {row.get("message") for row in answer.json()["rows"]}:
            return time.perf_counter()
        time.sleep(POLL_SECONDS)
    return None
