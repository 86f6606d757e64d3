"""The views kept by a process of their own, beside the API's (`segb serve`, VIEWS_PROCESS, on by default).

Keeping the views current (the reports' rows, the timeline's kinds, the graph index, the rules' findings) is
Python work of about the size of ingest itself, and one interpreter runs one thread's Python at a time: kept
by a thread of the API process, every post waited its turn behind the views' batches (one robot posting as fast
as answered: 80 posts/s with every view kept, 190 with none, on 2 cores). In a process of their own the views
run on the other core and the requests never wait for them.

The views' process runs at a lower priority than the requests (NICENESS), and so do the API process's threads
that answer its queries: where the cores are busy, the posts go first, and they wait for the views only when the
views fall further behind than VIEWS_MAX_LAG_SECONDS. The process that opens the store starts the views' process
and supervises it (`ViewsProcess`): one that exits is
started again, 1 s later and up to 30 s while it keeps failing. On the embedded store, which one process opens,
the views read it through the API process's channel (`store/channel.py`); on a remote store they open it
themselves. They read what to keep from the journal, up to the store's cursor (`WritePath`, `Role.VIEWS`), and
write the same files as ever, which the API processes read (`Role.API`). The views' process says how it is in a
small status file it rewrites every second (`ViewsStatus`): the API processes read there whether it runs, and
the error its views are retrying, for readiness and for posts (which do not wait for views that are failing).
It ends when the process that started it ends, however that ends.
"""

from __future__ import annotations

import contextlib
import json
import logging
import multiprocessing
import multiprocessing.connection
import os
import signal
import threading
import time
from enum import Enum
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from segb_server.backend.collector import tune_collector
from segb_server.backend.config import Settings
from segb_server.backend.services.views.channel import ChannelAddress

logger = logging.getLogger("segb.views")

STATUS_FILE = "views-status.json"
HEARTBEAT_SECONDS = 1.0  # how often the views' process rewrites its status
# A status older than this says the views' process is not running: well above a heartbeat delayed by a busy
# machine, well below the minutes a robot's posts would otherwise wait on views nobody keeps.
SILENT_SECONDS = 10.0
FIRST_RESTART_SECONDS = 1.0
MOST_RESTART_SECONDS = 30.0
HEALTHY_SECONDS = 60.0  # a process that ran this long before exiting is started again after the first delay
STOP_SECONDS = 20.0  # how long a stopping views' process may take to finish its batch before it is killed
# The views' work runs below the requests' priority, wherever it runs: the views' process, and the threads of the
# API process that answer its queries (which share the requests' interpreter). Where the cores are busy, a post
# then waits for no view: one robot as fast as answered, 186 posts/s with the reports 1.7 s behind at p99, against
# 155 and 0.7 s at the same priority (2 minutes each). Posts wait for the views when they fall further behind
# (VIEWS_MAX_LAG_SECONDS): the lower priority never lets them fall behind for good.
NICENESS = 5
CHANNEL_NICENESS = 10
_SPAWN = multiprocessing.get_context("spawn")


class ViewsHome(Enum):
    """Which process keeps the views an API process serves."""

    THIS = "this"  # a thread of this process (VIEWS_PROCESS=false, STORE=memory, tests in process)
    CHILD = "child"  # a process of their own, which this API process starts and supervises (`segb serve`)
    SIBLING = "sibling"  # a process of their own, started by the supervisor of the API workers (`--workers N`)


def views_home(settings: Settings, *, workers: bool) -> ViewsHome:
    """Where `segb serve` keeps the views: in a process of their own unless VIEWS_PROCESS or KEEP_VIEWS is off, or
    the store lives in this process's memory (nothing another process could read). VIEWS_PROCESS unset: on the
    embedded store only. There the views' Python no longer shares the requests' interpreter (one robot's soak: 114
    and 119 posts/s against 100 over 15 minutes); on Virtuoso the views in a process of their own, below the requests'
    priority, fell further behind and the posts waited for them (38 posts/s against 75 with the leading worker
    keeping them: docs/scaling.md)."""
    wanted = settings.store == "oxigraph" if settings.views_process is None else settings.views_process
    if not (wanted and settings.keep_views) or settings.store == "memory":
        return ViewsHome.THIS
    return ViewsHome.SIBLING if workers else ViewsHome.CHILD


class ViewsStatus:
    """The views' process's status file: written by that process, read by the API processes (at most every
    READ_SECONDS, whatever the number of posts asking)."""

    READ_SECONDS = 0.25

    def __init__(self, data_dir: Path) -> None:
        self.path = data_dir / STATUS_FILE
        self._read_at = float("-inf")
        self._known: dict[str, Any] | None = None
        self._lock = threading.Lock()

    # --- the views' process ------------------------------------------------------------------------------

    def write(self, outage: str | None, error: str | None, building_all: bool = False) -> None:
        """The views' process is alive; `outage`: the store or the views' storage away (every view waits);
        `error`: what readiness tells (the outage, or why views set aside are not built); `building_all`: every
        view is being built from the store (at start, or after an erasure)."""
        record = {"pid": os.getpid(), "at": time.time(), "outage": outage, "error": error, "building_all": building_all}
        temporary = self.path.with_name(f".{self.path.name}.{os.getpid()}")
        temporary.write_text(json.dumps(record))
        os.replace(temporary, self.path)  # a reader sees the old record or the new one, whole

    def remove(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    # --- the API processes ---------------------------------------------------------------------------------

    def down(self) -> str | None:
        """Why the views are not being kept just now (None while their process runs)."""
        record = self._record()
        if record is None:
            return "the views' process is not running"
        silent = time.time() - float(record["at"])
        if silent > SILENT_SECONDS:
            return f"the views' process (pid {record['pid']}) has not been heard from for {silent:.0f} s"
        return None

    def outage(self) -> str | None:
        record = self._record()
        return None if record is None else record.get("outage")

    def error(self) -> str | None:
        record = self._record()
        return None if record is None else record.get("error")

    def building_all(self) -> bool:
        record = self._record()
        return record is not None and bool(record.get("building_all"))

    def _record(self) -> dict[str, Any] | None:
        with self._lock:
            if time.monotonic() - self._read_at >= self.READ_SECONDS:
                try:
                    self._known = json.loads(self.path.read_text())
                except (FileNotFoundError, ValueError):  # not written yet, or being replaced on a system without
                    self._known = None  # atomic renames
                self._read_at = time.monotonic()
            return self._known


class ViewsProcess:
    """Starts the views' process and starts it again whenever it exits, until `stop`."""

    def __init__(self, settings: Settings, channel: ChannelAddress | None) -> None:
        self.settings = settings
        self.channel = channel
        self.started = 0  # processes started so far
        self.process: BaseProcess | None = None
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    def start(self) -> None:
        self._thread = threading.Thread(target=self._supervise, name="segb-views-supervisor", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Ask the views' process to finish its batch and exit (killed after STOP_SECONDS). Only the supervising
        thread reaps it: a second thread joining the same process may find it reaped already by the first, take
        it for alive, and report a kill that never was."""
        self._stopping.set()
        with self._lock:
            process = self.process
        if process is not None:
            process.terminate()  # SIGTERM: the batch under way is finished and kept (nothing, once it has exited)
            # Its sentinel is readable once it has exited, whoever reaps it.
            if not multiprocessing.connection.wait([process.sentinel], STOP_SECONDS):
                logger.warning(
                    "the views' process (pid %s) did not stop within %g s; killed", process.pid, STOP_SECONDS
                )
                process.kill()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def _supervise(self) -> None:
        delay = FIRST_RESTART_SECONDS
        while not self._stopping.is_set():
            with self._lock:
                if self._stopping.is_set():
                    return
                process = self.process = _SPAWN.Process(
                    target=keep_views, args=(self.settings, self.channel), name="segb-views", daemon=True
                )
                process.start()
                self.started += 1
            began = time.monotonic()
            logger.info("the views' process started (pid %s)", process.pid)
            process.join()
            ViewsStatus(self.settings.data_dir).remove()  # at once, not once its last heartbeat is old
            if self._stopping.is_set():
                return
            if time.monotonic() - began >= HEALTHY_SECONDS:
                delay = FIRST_RESTART_SECONDS
            logger.error(
                "the views' process (pid %s) exited with %s; starting it again in %g s",
                process.pid,
                _exit_status(process.exitcode),
                delay,
            )
            if self._stopping.wait(delay):
                return
            delay = min(2 * delay, MOST_RESTART_SECONDS)


def _exit_status(code: int | None) -> str:
    if code is not None and code < 0:
        return f"signal {signal.Signals(-code).name}"
    return f"code {code}"


# --- the views' process itself ------------------------------------------------------------------------------


def keep_views(settings: Settings, channel: ChannelAddress | None) -> None:
    """The views' process: keep every view current until told to stop (SIGTERM, SIGINT) or until the process
    that started it ends."""
    from segb_server.backend.services.container import REQUIRED_QUERIES, build_views
    from segb_server.backend.services.ops.server_log import ServerLog
    from segb_server.backend.services.sparql.catalog import Catalog
    from segb_server.backend.services.views.channel import ChannelStore
    from segb_server.backend.services.writing.write_path import Role, WritePath
    from segb_server.backend.serving import configure_logging
    from segb_server.backend.store.factory import open_store

    os.nice(NICENESS)
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):  # Ctrl-C reaches the whole process group: finish the batch
        signal.signal(signum, lambda *_: stop.set())
    configure_logging(settings)
    server_log = ServerLog.from_settings(settings)
    server_log.install()
    threading.Thread(target=_end_with_parent, args=(stop,), name="segb-views-parent", daemon=True).start()
    status = ViewsStatus(settings.data_dir)
    store = ChannelStore(channel) if channel is not None else open_store(settings)
    views = build_views(settings, store, Catalog(settings.sparql_dir, required=REQUIRED_QUERIES))
    writes = WritePath.open(settings, store, views.kept, views.housekeeping, Role.VIEWS)
    try:
        # Told to stop while opening (a server stopped as it starts): no build of every view is begun only to be
        # waited for, past the STOP_SECONDS after which this process is killed.
        if not stop.is_set():
            writes.start()
            tune_collector()
        while not stop.is_set():
            status.write(writes.keeper.outage, writes.keeper.last_error, writes.keeper.building_all)
            stop.wait(HEARTBEAT_SECONDS)
    finally:
        writes.close()  # the batch under way is finished first
        views.close()
        store.close()
        status.remove()
        server_log.uninstall()


def _end_with_parent(stop: threading.Event) -> None:
    """Set `stop` once the process that started this one has ended (killed, crashed or done)."""
    parent = multiprocessing.parent_process()
    if parent is not None:
        multiprocessing.connection.wait([parent.sentinel])
        stop.set()
