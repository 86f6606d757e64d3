"""Live traces: each activity a post brings is read from the store once applied and sent to the OTLP endpoint.

The applier's listener only notes the new activities (it must not wait); a thread of its own reads and sends
them. Its queue is bounded: when the endpoint is slow or away, what does not fit is dropped and counted
(`segb_traces_dropped_total`), and posts never wait. Read from the store when sent, so an activity whose person
was erased meanwhile is sent without them: after an erasure nothing about that person is sent again.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading

from pyoxigraph import NamedNode

from segb_server.backend.services.errors import OUTAGES
from segb_server.backend.services.observability.metrics import TRACES_DROPPED
from segb_server.backend.services.observability.otlp import ExportFailed, exporter, rows, send
from segb_server.backend.services.observability.spans import spans_of
from segb_server.backend.services.sparql.catalog import CatalogQuery
from segb_server.backend.services.writing.applier import Applied
from segb_server.backend.store.base import Store
from segb_server.backend.vocabulary import PERFORMED_BY

logger = logging.getLogger("segb.traces")

QUEUE_SIZE = 10_000  # activities waiting to be sent
ROOTS_REMEMBERED = 10_000  # interactions whose root span this process sent
_PERFORMED_BY = NamedNode(PERFORMED_BY)


class LiveTraces:
    def __init__(self, store: Store, query: CatalogQuery, endpoint: str, *, with_text: bool,
                 queue_size: int = QUEUE_SIZE) -> None:  # fmt: skip
        self.store = store
        self.query = query
        self.with_text = with_text
        self.export = exporter(endpoint)
        self._queue: queue.Queue[str | None] = queue.Queue(maxsize=queue_size)
        self._roots: set[str] = set()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="segb-live-traces", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Stop before the store closes: what is still queued is not sent."""
        self._stopping.set()
        self.export.shutdown()  # an export retrying meanwhile gives up at once
        with contextlib.suppress(queue.Full):  # a full queue: the thread sees the stop at its next
            self._queue.put_nowait(None)
        self._thread.join(timeout=5)

    def applied(self, step: Applied) -> None:
        """The applier's listener: note the activities the step brought (never waits)."""
        if step.erased:
            self._roots.clear()  # a root span names the person its interaction was about
        for quad in step.quads:
            if quad.predicate == _PERFORMED_BY and isinstance(quad.subject, NamedNode):
                try:
                    self._queue.put_nowait(quad.subject.value)
                except queue.Full:
                    TRACES_DROPPED.inc()

    def _run(self) -> None:
        while True:
            activity = self._queue.get()
            if activity is None or self._stopping.is_set():
                return
            try:
                found = rows(self.store, self.query, {"activity": activity})
                if len(self._roots) > ROOTS_REMEMBERED:
                    self._roots.clear()
                send(self.export, spans_of(found, with_text=self.with_text, roots_sent=self._roots))
            except ExportFailed as failed:
                TRACES_DROPPED.inc()
                logger.warning("trace of %s not sent: %s", activity, failed)
            except OUTAGES as error:
                TRACES_DROPPED.inc()
                logger.warning("trace of %s not read: %s", activity, error)
