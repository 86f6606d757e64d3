"""Readiness sampled beside a load: how long `/healthz/ready` takes, and how far the store (`apply_lag`) and the
reports' rows (`reports_lag`) are behind the journal while and after the load runs."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

import httpx

from bench.measure import Latency


@dataclass(frozen=True)
class LagSample:
    apply_entries: int
    apply_seconds: float
    reports_entries: int


def lag_of(body: dict[str, Any]) -> LagSample:
    applying = body.get("apply_lag") or {}
    reports = body.get("reports_lag") or {}
    return LagSample(
        int(applying.get("entries", 0)), float(applying.get("seconds", 0.0)), int(reports.get("entries", 0))
    )


@dataclass
class ReadinessProbe:
    """`with ReadinessProbe(url) as probe:` polls `/healthz/ready` every `interval` seconds in a thread until
    the block ends; `probe.latencies` (seconds) and `probe.samples` hold what it saw."""

    url: str
    interval: float = 0.05
    latencies: list[float] = field(default_factory=list)
    samples: list[LagSample] = field(default_factory=list)
    errors: int = 0

    def __post_init__(self) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bench-readiness", daemon=True)

    def __enter__(self) -> ReadinessProbe:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        with httpx.Client(base_url=self.url, timeout=10) as client:
            while not self._stop.is_set():
                begin = time.perf_counter()
                try:
                    body = client.get("/healthz/ready").json()
                except (httpx.HTTPError, ValueError):
                    self.errors += 1
                else:
                    self.latencies.append(time.perf_counter() - begin)
                    self.samples.append(lag_of(body))
                self._stop.wait(self.interval)

    def latency(self) -> Latency | None:
        return Latency.of(self.latencies) if self.latencies else None


@dataclass(frozen=True)
class Drain:
    """How long after a load ended the store, then the reports' rows, caught up with the journal (seconds;
    None when they had not within the time allowed)."""

    apply_seconds: float | None
    reports_seconds: float | None


def wait_caught_up(url: str, timeout: float = 600, interval: float = 0.02) -> Drain:
    """Poll `/healthz/ready` from now until neither `apply_lag` nor `reports_lag` is reported."""
    started = time.perf_counter()
    applied: float | None = None
    with httpx.Client(base_url=url, timeout=10) as client:
        while time.perf_counter() - started < timeout:
            lag = lag_of(client.get("/healthz/ready").json())
            now = time.perf_counter() - started
            if applied is None and not lag.apply_entries:
                applied = now
            if applied is not None and not lag.reports_entries:
                return Drain(applied, now)
            time.sleep(interval)
    return Drain(applied, None)


@dataclass(frozen=True)
class LagFigures:
    """What the readiness probe saw during a load, and how long the lag took to go once it ended."""

    samples: int
    behind_samples: int  # samples that reported any apply_lag
    max_entries: int
    max_seconds: float
    max_reports_entries: int
    drain: Drain

    @classmethod
    def of(cls, samples: list[LagSample], drain: Drain) -> LagFigures:
        return cls(
            samples=len(samples),
            behind_samples=sum(1 for sample in samples if sample.apply_entries),
            max_entries=max((sample.apply_entries for sample in samples), default=0),
            max_seconds=max((sample.apply_seconds for sample in samples), default=0.0),
            max_reports_entries=max((sample.reports_entries for sample in samples), default=0),
            drain=drain,
        )
