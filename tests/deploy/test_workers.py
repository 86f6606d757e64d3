"""`segb serve --workers N` on a real Virtuoso: several API processes on one port and one data directory.

Robots post to whichever worker the kernel hands their connection; afterwards every acknowledged triple is
stored, the journal is one valid hash chain with exactly one receipt per post, concurrent shared-context
resolutions agree, and a live report stream on one worker hears of posts taken by the others. Then the
leader is killed and another worker takes over applying."""

from __future__ import annotations

import contextlib
import http.client
import json
import os
import signal
import subprocess
import threading
import time
import uuid
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from urllib.parse import urlsplit

import httpx
import psycopg
import pytest

from segb_server.backend.state.postgres import lock_key
from tests.cli.test_cli import SEGB, clean_env, segb, wait_for
from tests.faults.test_crashes import all_receipts, caught_up, check_consistent, post_turtle
from tests.support.net import free_port
from tests.support.scenarios import lobby
from tests.support.virtuoso import VirtuosoProcess

pytestmark = pytest.mark.virtuoso

ROBOTS = 16
EX = "https://example.org/workers/"
POSTS_PER_ROBOT = 100


class Workers:
    """`segb serve --only api --workers N` on Virtuoso, as a process group of its own."""

    def __init__(
        self,
        virtuoso: VirtuosoProcess,
        data_dir: Path,
        workers: int,
        *,
        ui: bool = False,
        graph_uri: str | None = None,
        state_url: str = "",
    ) -> None:
        """`graph_uri`: the store's graph (a new one unless given); `state_url`: STATE_URL (empty: SQLite)."""
        self.port, self.ui_port = free_port(), free_port()
        self.state_url = state_url
        self.url = f"http://127.0.0.1:{self.port}"
        self.data_dir = data_dir
        self.env = {
            "STORE": "virtuoso",
            "VIRTUOSO_ENDPOINT": virtuoso.endpoint,
            "VIRTUOSO_USER": virtuoso.user,
            "VIRTUOSO_PASSWORD": virtuoso.password,
            "VIRTUOSO_GRAPH_URI": graph_uri or f"http://amor-segb/test/{uuid.uuid4().hex}",
            "STATE_URL": state_url,
        }
        command = ["serve", *([] if ui else ["--only", "api"]), "--workers", str(workers), "--data-dir", str(data_dir)]
        self.log = data_dir.with_name(f"{data_dir.name}.log")  # a file: a pipe nobody reads would stall the server
        with self.log.open("wb") as log:
            self.process = subprocess.Popen(
                [*SEGB, *command, "--api-port", str(self.port), "--ui-port", str(self.ui_port)],
                env=clean_env(self.env),
                stdout=subprocess.DEVNULL,
                stderr=log,
                start_new_session=True,
            )
        wait_for(f"{self.url}/healthz/live")

    def leader(self) -> int:
        """The process that applies the journal (with SQLite state, the one holding the data directory's lock)."""
        if self.state_url:
            return applier_pid(self.state_url)
        return int((self.data_dir / "leader.lock").read_text().strip())

    def stop(self) -> str:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        return self.log.read_text(errors="replace")


def applier_pid(url: str) -> int:
    """The process holding the applier's lock, as PostgreSQL sees it (servers name their connections); 0 while
    nobody holds it."""
    with psycopg.connect(url) as connection:
        row = connection.execute(
            "SELECT a.application_name FROM pg_locks l JOIN pg_stat_activity a ON a.pid = l.pid "
            "WHERE l.locktype = 'advisory' AND l.granted AND ((l.classid::bigint << 32) | l.objid::bigint) = %s",
            (lock_key("leader:applier"),),
        ).fetchone()
    return 0 if row is None else int(row[0].removeprefix("segb-server "))


@pytest.fixture
def start_workers(virtuoso: VirtuosoProcess, tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[object]:
    """Starts workers; with `state="postgresql"` their state is in a new database on a real PostgreSQL."""
    started: list[Workers] = []

    def start(workers: int, ui: bool = False, state: str = "sqlite") -> Workers:
        state_url = request.getfixturevalue("postgres_url") if state == "postgresql" else ""
        started.append(Workers(virtuoso, tmp_path / f"data-{len(started)}", workers, ui=ui, state_url=state_url))
        return started[-1]

    yield start
    for running in started:
        log = running.stop()
        # Shown with a failure's report only: what the supervisor and the workers said besides the requests
        # (a worker that died or was replaced, a traceback), the evidence a reset connection needs.
        print(f"--- {running.log.name}, besides the requests ---")
        print("\n".join(line for line in log.splitlines() if "segb.requests" not in line)[-20000:])


def post_all(url: str) -> dict[str, str]:
    """16 robots, 100 distinct posts each, every one on a new connection (so spread over the workers)."""
    acknowledged: dict[str, str] = {}
    failures: list[str] = []
    lock = threading.Lock()

    def robot(number: int) -> None:
        for post in range(POSTS_PER_ROBOT):
            turtle = post_turtle(number, post)
            status, answer = post_json(url, "/ttl", {"ttl_content": turtle, "user": f"robot{number}"})
            with lock:
                if status == 201:
                    acknowledged[answer["log_id"]] = turtle
                else:
                    failures.append(f"{status} {answer}")

    with ThreadPoolExecutor(ROBOTS) as pool:
        list(pool.map(robot, range(ROBOTS)))
    assert failures == []
    return acknowledged


def post_json(
    url: str, path: str, body: dict[str, object], headers: dict[str, str] | None = None
) -> tuple[int, dict[str, object]]:
    """One POST on a connection of its own (as the PyPI client makes them), so the kernel picks the worker;
    http.client, because a new httpx client per request costs the test more CPU than the server's work."""
    address = urlsplit(url)
    connection = http.client.HTTPConnection(address.hostname or "", address.port, timeout=60)
    try:
        sent = {"Content-Type": "application/json", **(headers or {})}
        connection.request("POST", path, body=json.dumps(body), headers=sent)
        answer = connection.getresponse()
        return answer.status, json.loads(answer.read())
    finally:
        connection.close()


# Rounds of simultaneous posts a test tries before it gives up on the kernel spreading them: on a loaded machine
# one worker may take every connection of ten rounds in a row (seen once in a full run).
SPREAD_ROUNDS = 30


def post_until_spread(url: str, robot: int, rounds: int = SPREAD_ROUNDS) -> dict[str, str]:
    """Rounds of 16 simultaneous posts by `robot`, until one round was served by more than one worker (the
    kernel picks; posts that come one at a time tend to find the same idle worker). Returns what was
    acknowledged: log_id → the Turtle sent."""
    acknowledged: dict[str, str] = {}

    def post(number: int, round_number: int) -> None:
        turtle = post_turtle(robot, number)
        request_id = f"spread-{robot}-{round_number}-{number}"
        body = {"ttl_content": turtle, "user": f"robot{robot}"}
        status, answer = post_json(url, "/ttl", body, {"X-Request-ID": request_id})
        assert status == 201, answer
        acknowledged[str(answer["log_id"])] = turtle

    for round_number in range(rounds):
        numbers = range(round_number * 16, (round_number + 1) * 16)
        with ThreadPoolExecutor(16) as pool:
            list(pool.map(post, numbers, [round_number] * 16))
        if len(processes_serving(url, "/ttl", f"spread-{robot}-{round_number}-")) >= 2:
            return acknowledged
    raise AssertionError("the posts were never spread over the workers")


def post_message(url: str, message: str, round_number: int) -> int:
    """A robot's message, the least the conversations report shows, on a connection of its own."""
    activity = f"{message}/activity"
    turtle = (
        f'<{message}> a <http://schema.org/Message> ; <http://schema.org/text> "hello"@en ; '
        f"<http://www.w3.org/ns/prov#wasGeneratedBy> <{activity}> .\n"
        f"<{activity}> <http://www.gsi.upm.es/ontologies/segb/ns#wasPerformedBy> <{EX}robot/ari> .\n"
    )
    request_id = f"message-{round_number}-{message.rsplit('-', 1)[-1]}"
    status, _ = post_json(url, "/ttl", {"ttl_content": turtle, "user": "ari"}, {"X-Request-ID": request_id})
    return status


def processes_serving(url: str, path: str, request_ids: str = "") -> set[int]:
    """The worker processes that logged a request to `path` (whose id starts with `request_ids`)."""
    entries = httpx.get(f"{url}/logs/server", params={"limit": 2000, "contains": path}, timeout=30).json()["entries"]
    return {
        entry["process"]
        for entry in entries
        if entry.get("path") == path and str(entry.get("request_id", "")).startswith(request_ids)
    }


STATES = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]


@pytest.mark.parametrize("state", STATES)
@pytest.mark.parametrize("workers", [2, 4])
def test_robots_posting_to_several_workers_make_one_chain_and_lose_nothing(
    start_workers: object, workers: int, state: str
) -> None:
    server = start_workers(workers, state=state)  # type: ignore[operator]
    acknowledged = post_all(server.url)
    assert len(acknowledged) == ROBOTS * POSTS_PER_ROBOT
    caught_up(server.url)
    check_consistent(server.url, acknowledged)  # stored, receipted, and the chain verifies deep
    receipts = list(all_receipts(server.url))
    assert sorted(receipt["sequence"] for receipt in receipts) == list(range(1, len(acknowledged) + 1))
    assert {receipt["log_id"] for receipt in receipts} == set(acknowledged)  # one receipt per post, no other
    assert len(processes_serving(server.url, "/ttl")) >= 2, "every post went to one worker: nothing was shared"


def worker_pids(server: Workers) -> set[int]:
    """The API worker processes under the supervisor (uvicorn spawns them; its resource tracker is not one)."""
    children = Path(f"/proc/{server.process.pid}/task/{server.process.pid}/children").read_text().split()
    return {int(pid) for pid in children if b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes()}


def test_a_worker_that_cannot_answer_for_seconds_is_not_killed(start_workers: object) -> None:
    """On a loaded machine a busy worker may not answer the supervisor's ping for seconds; uvicorn's default
    kills it after 5 s, resetting every connection it holds. A worker frozen for 8 s stays, and posts meanwhile
    go to the other one."""
    server = start_workers(2)  # type: ignore[operator]
    deadline = time.monotonic() + 30
    while len(workers := worker_pids(server)) < 2 and time.monotonic() < deadline:
        time.sleep(0.2)
    assert len(workers) == 2, workers
    frozen = next(pid for pid in workers if pid != server.leader())
    os.kill(frozen, signal.SIGSTOP)
    try:
        started = time.monotonic()
        statuses = []
        while time.monotonic() - started < 8:
            status, _ = post_json(server.url, "/ttl", {"ttl_content": post_turtle(1, len(statuses)), "user": "r"})
            statuses.append(status)
            time.sleep(0.2)
    finally:
        with contextlib.suppress(ProcessLookupError):  # gone: killed by the supervisor, which the test fails on
            os.kill(frozen, signal.SIGCONT)
    time.sleep(2)  # the supervisor pings every half second: a kill would have happened by now
    assert set(statuses) == {201}
    assert worker_pids(server) == workers, "the supervisor replaced the frozen worker"
    assert "died" not in server.log.read_text(errors="replace")


@pytest.mark.parametrize("state", STATES)
def test_concurrent_resolutions_across_workers_give_one_context(start_workers: object, state: str) -> None:
    """Rounds of 16 simultaneous resolutions of one observation (each round a new one), until three rounds were
    served by more than one worker (the kernel picks; a round is too quick to be always spread, and one worker
    may take every connection of ten rounds in a row: SPREAD_ROUNDS for each spread round wanted)."""
    server = start_workers(2, state=state)  # type: ignore[operator]
    spread_rounds = 0
    for round_number in range(2 * SPREAD_ROUNDS):
        body = {
            "event_kind": "human_utterance",
            "observed_at": f"2026-05-04T10:{round_number:02d}:00+00:00",
            "subject_uri": "https://example.org/people/maria",
            "modality": "speech",
            "text": f"Good morning, robot! ({round_number})",
        }

        def resolve(call: int, body: dict[str, object] = body, round_number: int = round_number) -> str:
            request_id = f"round{round_number}-{call}"
            status, answer = post_json(server.url, "/shared-context/resolve", body, {"X-Request-ID": request_id})
            assert status == 200, answer
            return str(answer["shared_context_uri"])

        with ThreadPoolExecutor(16) as pool:
            uris = set(pool.map(resolve, range(16)))
        assert len(uris) == 1, f"round {round_number}: {uris}"
        if len(processes_serving(server.url, "/shared-context/resolve", f"round{round_number}-")) >= 2:
            spread_rounds += 1
            if spread_rounds >= 3:
                break
    assert spread_rounds >= 3, "the resolutions were never spread over the workers"


@pytest.mark.parametrize("state", STATES)
def test_a_report_stream_hears_of_posts_taken_by_other_workers_and_the_lead_moves_on(
    start_workers: object, state: str
) -> None:
    server = start_workers(2, state=state)  # type: ignore[operator]
    caught_up(server.url)
    heard: set[str] = set()
    listening = threading.Event()

    def listen() -> None:
        # Ends with an error when its worker is killed below, or the server stops: what it heard is kept.
        with (
            contextlib.suppress(httpx.HTTPError),
            httpx.stream(
                "GET", f"{server.url}/reports/stream", params={"report": "conversations"}, timeout=120
            ) as stream,
        ):
            listening.set()
            for line in stream.iter_lines():
                if line.startswith("data:") and "units" in line:
                    heard.update(json.loads(line[5:])["units"])

    threading.Thread(target=listen, daemon=True).start()
    assert listening.wait(30)
    lobby().publish_all(server.url)  # the PyPI client, through whichever workers
    sent: set[str] = set()
    for round_number in range(SPREAD_ROUNDS):  # rounds of 16 simultaneous posts, until spread over the workers
        messages = [f"{EX}message/{round_number}-{call}" for call in range(16)]
        with ThreadPoolExecutor(16) as pool:
            statuses = list(pool.map(post_message, [server.url] * 16, messages, [round_number] * 16))
        assert statuses == [201] * 16
        sent.update(messages)
        if len(processes_serving(server.url, "/ttl", f"message-{round_number}-")) >= 2:
            break
    else:
        raise AssertionError("the posts were never spread over the workers")
    deadline = time.monotonic() + 10
    unheard = sent
    while unheard and time.monotonic() < deadline:
        time.sleep(0.1)
        unheard = {message for message in sent if not any(message in unit for unit in set(heard))}
    assert not unheard, f"the stream never mentioned {sorted(unheard)[:5]}"
    conversations = httpx.get(f"{server.url}/reports/conversations", params={"limit": 1000}, timeout=30).json()
    assert sent <= {str(row["message"]) for row in conversations["rows"]}

    # The leader dies (SIGKILL): a follower takes the lock over and applies what is posted next.
    leader = server.leader()
    assert leader, "no worker applies"
    os.kill(leader, signal.SIGKILL)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and server.leader() in (leader, 0):
        time.sleep(0.2)
    assert server.leader() not in (leader, 0), "no worker took the lead over"
    turtle = post_turtle(99, 0)
    answer = httpx.post(f"{server.url}/ttl", json={"ttl_content": turtle, "user": "late"}, timeout=30)
    assert answer.status_code == 201, answer.text
    caught_up(server.url)
    check_consistent(server.url, {answer.json()["log_id"]: turtle})


def test_the_ui_runs_beside_the_workers_and_a_rebuild_waits_for_them_to_stop(start_workers: object) -> None:
    server = start_workers(2, ui=True)  # type: ignore[operator]
    page = wait_for(f"http://127.0.0.1:{server.ui_port}/health")
    assert "Ready" in page.text
    refused = segb("rebuild", "--store", "virtuoso", "--data-dir", str(server.data_dir), env=server.env)
    assert refused.returncode == 2
    assert "a server is running" in refused.stderr


@pytest.mark.parametrize(
    ("arguments", "problem"),
    [
        (["--store", "oxigraph"], "needs a store the workers can share (STORE=virtuoso or sparql)"),
        (["--store", "memory"], "needs a store the workers can share"),
        (["--store", "virtuoso", "--demo"], "--demo loads the demo in one process"),
    ],
)
def test_workers_are_refused_where_they_cannot_share(tmp_path: Path, arguments: list[str], problem: str) -> None:
    refused = segb("serve", "--workers", "2", "--data-dir", str(tmp_path), *arguments)
    assert refused.returncode == 2
    assert problem in refused.stderr
    assert not (tmp_path / "leader.lock").exists()  # refused before anything was opened


@pytest.mark.parametrize("state", STATES)
def test_an_erasure_is_one_entry_every_worker_follows(start_workers: object, state: str) -> None:
    """Erased through whichever worker takes the request, the person is gone from what every worker answers, the
    chain has one erasure in it, and a re-publish to any worker holds her triples back."""
    from tests.support.people import INES_SAYS, care_home
    from tests.support.settle import settle

    server = start_workers(2, state=state)  # type: ignore[operator]
    visit = care_home()
    visit.publish_steps(server.url)
    ines = str(visit.iris["ines"])
    answer = httpx.post(f"{server.url}/humans/erase", json={"iri": ines, "reason": "request"}, timeout=300)
    assert answer.status_code == 200, answer.text
    settle(server.url, timeout=120)
    answered_by: set[int] = set()
    for round_number in range(40):
        request_id = f"erased-{round_number}"
        stored = httpx.get(f"{server.url}/events", params={"format": "ntriples"}, headers={"X-Request-ID": request_id})
        assert INES_SAYS[0] not in stored.text and ines not in stored.text
        rows = httpx.get(f"{server.url}/reports/participants", params={"human": ines}).json()["rows"]
        assert rows == []
        answered_by |= processes_serving(server.url, "/events", request_id)
        if len(answered_by) == 2:
            break
    assert len(answered_by) == 2, "one worker answered every read"
    withheld = sum(post["triples_withheld"] for _ in range(3) for post in visit.publish(server.url))
    assert withheld == 3 * answer.json()["triples_removed"]
    receipts = list(all_receipts(server.url))
    assert [receipt["action"] for receipt in receipts].count("erase") == 1
    verified = httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}, timeout=120).json()
    assert verified["valid"] is True and verified["redactions"] == 1
