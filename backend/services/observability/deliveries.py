"""Webhook deliveries: a bounded queue and one thread that posts each event to every URL, retried with backoff.

Nothing that records a post waits for it: an event that finds the queue full is dropped, logged and counted
(`segb_webhook_deliveries_total{outcome="dropped"}`). The latest deliveries are remembered (in memory, until
the next erasure, since their bodies name people) so an operator can send one again.
"""

from __future__ import annotations

import contextlib
import json
import logging
import queue
import threading
import uuid
from collections import OrderedDict
from dataclasses import dataclass, field

import httpx

from segb_server.backend.services.errors import NotFound
from segb_server.backend.services.observability.metrics import WEBHOOK_DELIVERIES
from segb_server.backend.services.observability.signing import HEADER, signature

logger = logging.getLogger("segb.webhooks")

QUEUE_SIZE = 1000
REMEMBERED = 500
ATTEMPTS = 5
FIRST_RETRY_SECONDS = 0.5  # then doubled: 0.5, 1, 2, 4 s between the five attempts
TIMEOUT_SECONDS = 5.0


@dataclass
class Delivery:
    id: str
    event: str  # finding.new or finding.resolved
    body: bytes
    outcomes: dict[str, str] = field(default_factory=dict)  # URL → delivered, or the last failure


class Deliveries:
    def __init__(
        self, urls: list[str], secret: str, *, queue_size: int = QUEUE_SIZE, first_retry: float = FIRST_RETRY_SECONDS
    ) -> None:
        self.urls = urls
        self.secret = secret
        self.first_retry = first_retry
        self._queue: queue.Queue[Delivery | None] = queue.Queue(maxsize=queue_size)
        self._remembered: OrderedDict[str, Delivery] = OrderedDict()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._client = httpx.Client(timeout=TIMEOUT_SECONDS)
        self._thread = threading.Thread(target=self._run, name="segb-webhooks", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        with contextlib.suppress(queue.Full):  # a full queue has a delivery that will see the stop
            self._queue.put_nowait(None)  # wakes the thread
        self._thread.join(timeout=TIMEOUT_SECONDS + 1)
        self._client.close()

    def send(self, event: str, payload: dict[str, object]) -> Delivery:
        """Queue `payload` for every URL; never waits (a full queue drops it)."""
        delivery_id = uuid.uuid4().hex
        body = json.dumps({"event": event, "delivery": delivery_id, **payload}, sort_keys=True).encode()
        delivery = Delivery(delivery_id, event, body)
        self._enqueue(delivery)
        return delivery

    def redeliver(self, delivery_id: str) -> Delivery:
        """Send a remembered delivery again (same id and body, signed anew); NotFound when it is not remembered."""
        with self._lock:
            delivery = self._remembered.get(delivery_id)
        if delivery is None:
            raise NotFound(f"No remembered webhook delivery {delivery_id!r} (the latest {REMEMBERED} are kept).")
        self._enqueue(delivery)
        return delivery

    def remembered(self) -> list[Delivery]:
        with self._lock:
            return list(reversed(self._remembered.values()))

    def forget(self) -> None:
        """An erasure happened: remembered bodies may name the person."""
        with self._lock:
            self._remembered.clear()

    def _enqueue(self, delivery: Delivery) -> None:
        try:
            self._queue.put_nowait(delivery)
        except queue.Full:
            WEBHOOK_DELIVERIES.labels("dropped").inc(len(self.urls))
            logger.warning("webhook %s %s dropped: %d deliveries wait already", delivery.event, delivery.id,
                           self._queue.maxsize)  # fmt: skip

    def _run(self) -> None:
        while True:
            delivery = self._queue.get()
            if delivery is None or self._stop.is_set():  # stopping: what still waits is not sent
                return
            with self._lock:
                self._remembered[delivery.id] = delivery
                self._remembered.move_to_end(delivery.id)
                while len(self._remembered) > REMEMBERED:
                    self._remembered.popitem(last=False)
            for url in self.urls:
                delivery.outcomes[url] = self._post(url, delivery)

    def _post(self, url: str, delivery: Delivery) -> str:
        wait = self.first_retry
        problem = ""
        for attempt in range(1, ATTEMPTS + 1):
            headers = {
                "Content-Type": "application/json",
                HEADER: signature(self.secret, delivery.body),
                "X-SEGB-Event": delivery.event,
                "X-SEGB-Delivery": delivery.id,
            }
            try:
                answer = self._client.post(url, content=delivery.body, headers=headers)
                if answer.status_code < 300:
                    WEBHOOK_DELIVERIES.labels("delivered").inc()
                    logger.info("webhook %s %s delivered to %s (attempt %d)", delivery.event, delivery.id, url, attempt)
                    return "delivered"
                problem = f"HTTP {answer.status_code}"
            except httpx.HTTPError as error:
                problem = f"{type(error).__name__}: {error}"
            logger.warning("webhook %s %s to %s: attempt %d failed (%s)", delivery.event, delivery.id, url, attempt,
                           problem)  # fmt: skip
            if attempt < ATTEMPTS and self._stop.wait(wait):
                break
            wait *= 2
        WEBHOOK_DELIVERIES.labels("failed").inc()
        return f"failed: {problem}"
