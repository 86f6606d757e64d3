"""Running the API and the UI: in one process (the default), or the API in N worker processes on one port.

`segb serve --workers N`: uvicorn's supervisor binds the port once and runs N worker processes on it (replacing
any that dies); the kernel spreads connections over them. Each worker builds its app from the environment, so
the settings given on the command line are handed down as environment variables. Every worker accepts posts
(the journal's SQLite transactions keep one hash chain) and serves reads; one of them, the holder of the
leadership lock (services/ops/leadership.py), also applies the journal and keeps the views current. Only a
remote store can be shared so: the embedded store is opened by one process. With the embedded store the views
are kept by a process of their own that the one API process starts (VIEWS_PROCESS, `backend/services/views/process.py`);
with VIEWS_PROCESS=true on a remote store, by one the supervisor of the workers starts.
"""

from __future__ import annotations

import asyncio
import contextlib
import contextvars
import errno
import ipaddress
import logging
import multiprocessing
import os
import signal
import socket
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import uvicorn

from segb_server.backend.collector import tune_collector
from segb_server.backend.config import Settings
from segb_server.backend.listening import CannotListen, Listener
from segb_server.backend.services.views.process import ViewsHome, ViewsProcess, views_home

if TYPE_CHECKING:
    from fastapi import FastAPI

logger = logging.getLogger("segb.serve")

APP_FACTORY = "segb_server.backend.serving:worker_app"
SHARED_STORES = ("virtuoso", "sparql")
# Live event streams never end by themselves: on shutdown they are closed after this long instead of holding
# the exit. A post cut so keeps nothing: its journal transaction never committed.
GRACEFUL_SHUTDOWN_SECONDS = 5
# uvicorn's supervisor kills a worker that has not answered its ping for this long, and with it every request
# the worker holds (their clients see their connection reset). Its default, 5 s, kills healthy workers on a
# loaded machine, where a busy worker's ping thread may wait that long for the interpreter; a worker that is
# really hung is still replaced, a minute later.
WORKER_HEALTHCHECK_SECONDS = 60


def configure_logging(settings: Settings) -> None:
    logging.basicConfig(level=settings.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    # httpx logs every request at INFO; the store monitor and the UI make many, and the API logs its own.
    logging.getLogger("httpx").setLevel(max(logging.WARNING, logging.getLevelName(settings.log_level)))
    # rdflib warns with a whole traceback for every literal whose text its datatype does not admit (a robot's
    # "2026-02-30T99:00:00Z"^^xsd:dateTime, read by the SHACL check): the literal is kept as sent, and a
    # traceback a post tells an operator nothing to act on.
    logging.getLogger("rdflib.term").setLevel(logging.ERROR)


def worker_app() -> FastAPI:
    """One worker process's app (uvicorn imports this by name in each), logging as `segb serve` does."""
    from segb_server.backend.api.app import create_app

    settings = Settings()
    configure_logging(settings)
    _name_process(api_listener(settings).what)
    app = create_app(settings, views_home=views_home(settings, workers=True))
    tune_collector()
    return app


class WorkersRefused(ValueError):
    """The settings cannot be served by several processes."""


def check_shareable(settings: Settings, *, demo: bool) -> None:
    if settings.api_workers > 1 and settings.store not in SHARED_STORES:
        raise WorkersRefused(
            f"API_WORKERS={settings.api_workers} needs a store the workers can share (STORE=virtuoso or sparql); "
            f"the {settings.store} store is opened by one process"
        )
    if settings.api_workers > 1 and demo:
        raise WorkersRefused("--demo loads the demo in one process: run one worker, or `segb demo` once it is up")


def listens_beyond_this_machine(host: str) -> bool:
    """Whether HOST lets other machines connect: anything but a loopback address or `localhost`."""
    if host == "localhost":
        return False
    try:
        return not ipaddress.ip_address(host).is_loopback
    except ValueError:  # a host name: it names some interface
        return True


def warn_when_open(settings: Settings) -> None:
    """Say loudly that an API without authentication listens where other machines may reach it."""
    if settings.auth_enabled or not listens_beyond_this_machine(settings.host):
        return
    logger.warning(
        "AUTHENTICATION IS OFF (SECRET_KEY is empty) and the API listens on %s: anyone who can reach port %d can "
        "publish, read and delete every log. Set SECRET_KEY (32+ random characters) to require tokens, or listen "
        "on 127.0.0.1 (HOST). With docker compose, PUBLISH_ADDRESS (127.0.0.1 unless changed) decides which "
        "machines reach the published port.",
        settings.host,
        settings.api_port,
    )


class DataDirUnwritable(ValueError):
    """The server cannot write its files in DATA_DIR."""


def check_data_dir(settings: Settings) -> None:
    """Fail with what to do, before serving, when DATA_DIR cannot be written (a root-owned folder mounted on a
    container's /data, whose server runs as an unprivileged user)."""
    if settings.store == "memory":
        return  # nothing is kept on disk
    folder = settings.data_dir
    places = (folder, folder / "logs")  # the server log is the first file written
    try:
        places[-1].mkdir(parents=True, exist_ok=True)
        for place in places:
            with tempfile.TemporaryFile(dir=place):
                pass
        # Files left by another user (an image that ran as root) are refused when opened, later: say so now.
        for path in (path for place in places for path in place.iterdir()):
            if not os.access(path, os.W_OK):
                raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
    except OSError as error:
        uid, gid = os.geteuid(), os.getegid()
        raise DataDirUnwritable(
            f"DATA_DIR {folder} is not writable by this server's user, uid {uid} ({error.strerror}: "
            f"{error.filename}): give the folder to that user: `sudo chown -R {uid}:{gid} {folder}` (for a host "
            f"folder mounted on {folder} in a container, run it on the host folder)"
        ) from error


def hand_down(overrides: Mapping[str, object]) -> None:
    """Settings from the command line, as the environment the worker processes build theirs from."""
    for name, value in overrides.items():
        os.environ[name.upper()] = str(value)


def _nothing() -> None:
    pass


def api_listener(settings: Settings) -> Listener:
    return Listener("API", settings.host, settings.api_port, "--api-port", "API_PORT")


def ui_listener(settings: Settings) -> Listener:
    return Listener("UI", settings.host, settings.ui_port, "--ui-port", "UI_PORT")


def serve(settings: Settings, *, api: bool, ui: bool, demo: bool, listening: Callable[[], None] = _nothing) -> None:
    """The API and/or the UI in this process, until Ctrl-C or SIGTERM stops both. Their ports are bound first,
    before the store is opened: a port that is taken raises CannotListen and nothing has started; `listening` is
    called once both are bound."""
    from segb_server.backend.api.app import create_app

    listeners = [*([api_listener(settings)] if api else []), *([ui_listener(settings)] if ui else [])]
    sockets: list[socket.socket] = []
    try:
        for listener in listeners:
            sockets.append(listener.open())
    except CannotListen:
        for opened in sockets:
            opened.close()
        raise
    listening()
    configs = []
    if api:
        app = create_app(settings, demo=demo, views_home=views_home(settings, workers=False))
        configs.append(uvicorn.Config(app, port=settings.api_port, **_options(settings)))
    if ui:
        configs.append(_ui_config(settings))
    tune_collector()
    servers = [
        _NamedServer(listener.what, _QuietServer(config), sock)
        for listener, config, sock in zip(listeners, configs, sockets, strict=True)
    ]
    # uvicorn's own choice of loop (uvloop when installed), which `asyncio.run` would bypass.
    with asyncio.Runner(loop_factory=configs[0].get_loop_factory()) as runner:
        runner.run(_serve_together(servers))


def serve_api_workers(settings: Settings, *, with_ui: bool, listening: Callable[[], None] = _nothing) -> None:
    """The API in `settings.api_workers` processes (and the UI in a process of its own) until stopped. The ports
    are checked first (uvicorn binds them itself): a port that is taken raises CannotListen."""
    api_listener(settings).check()
    if with_ui:
        ui_listener(settings).check()
    listening()
    ui = None
    if with_ui:
        ui = multiprocessing.get_context("spawn").Process(target=_serve_ui, name="segb-ui", daemon=True)
        ui.start()
    views = None
    if views_home(settings, workers=True) is ViewsHome.SIBLING:  # the workers share a remote store: no channel
        views = ViewsProcess(settings, None)
        views.start()
    try:
        workers = settings.api_workers
        uvicorn.run(
            APP_FACTORY,
            factory=True,
            workers=workers,
            port=settings.api_port,
            timeout_worker_healthcheck=WORKER_HEALTHCHECK_SECONDS,
            **_options(settings),
        )
    finally:
        if views is not None:
            views.stop()
        if ui is not None:
            ui.terminate()
            ui.join(timeout=10)


def _serve_ui() -> None:
    settings = Settings()
    configure_logging(settings)
    _name_process(ui_listener(settings).what)
    uvicorn.Server(_ui_config(settings)).run()


def _ui_config(settings: Settings) -> uvicorn.Config:
    from segb_server.ui.app import create_ui_app

    return uvicorn.Config(create_ui_app(settings), port=settings.ui_port, **_options(settings))


def _options(settings: Settings) -> dict[str, Any]:
    # No uvicorn access log: the API and UI log one line per request themselves. Only proxies in
    # FORWARDED_ALLOW_IPS may say the browser came over HTTPS (X-Forwarded-Proto): then the session and CSRF
    # cookies are Secure behind a TLS-terminating proxy.
    return {
        "host": settings.host,
        "access_log": False,
        "proxy_headers": True,
        "forwarded_allow_ips": settings.forwarded_allow_ips,
        "timeout_graceful_shutdown": GRACEFUL_SHUTDOWN_SECONDS,
    }


class _QuietServer(uvicorn.Server):
    """Leaves signals to `_serve_together`, which stops every server on Ctrl-C, not just the last one."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


@dataclass(frozen=True)
class _NamedServer:
    name: str  # API or UI, as the listeners call them
    server: uvicorn.Server
    sock: socket.socket


# The server whose task logs a record (each server is served in a task of its own, which copies the context).
_SERVING: contextvars.ContextVar[str] = contextvars.ContextVar("serving")
_PROCESS_LINES = ("Started server process", "Finished server process")


class _OneProcessTwoServers(logging.Filter):
    """Each uvicorn server logs the process's start and end, and its own startup and shutdown, in the same words:
    with the API and the UI in one process every line came twice. The process's lines are kept once (the first
    server's), and the others say which server they are about."""

    def __init__(self, first: str) -> None:
        super().__init__()
        self.first = first

    def filter(self, record: logging.LogRecord) -> bool:
        name = _SERVING.get(None)
        if name is None:
            return True
        if str(record.msg).startswith(_PROCESS_LINES):
            return name == self.first
        _say_which(record, name)
        return True


class _OneServer(logging.Filter):
    """With --workers, the UI and each API worker run in processes of their own, whose uvicorn lines are alike
    ("Started server process [pid]" three times for two workers and the UI): each says which server it runs."""

    def __init__(self, name: str) -> None:
        super().__init__()
        self.name = name

    def filter(self, record: logging.LogRecord) -> bool:
        _say_which(record, self.name)
        return True


def _name_process(name: str) -> None:
    """Prefix the uvicorn lines of this process, which runs the one server `name`, with that name."""
    logging.getLogger("uvicorn.error").addFilter(_OneServer(name))


def _say_which(record: logging.LogRecord, name: str) -> None:
    record.msg = f"{name}: {record.msg}"
    record.__dict__.pop("color_message", None)  # uvicorn's coloured copy of the message, without the name


async def _serve_together(servers: list[_NamedServer]) -> None:
    loop = asyncio.get_running_loop()

    def stop() -> None:
        for named in servers:
            named.server.should_exit = True

    async def serve(named: _NamedServer) -> None:
        _SERVING.set(named.name)
        await named.server.serve(sockets=[named.sock])

    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop)
    uvicorn_lines = logging.getLogger("uvicorn.error")
    named_lines = _OneProcessTwoServers(servers[0].name)
    if len(servers) > 1:
        uvicorn_lines.addFilter(named_lines)
    try:
        await asyncio.gather(*(serve(named) for named in servers))
    finally:
        uvicorn_lines.removeFilter(named_lines)
