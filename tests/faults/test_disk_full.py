"""The data directory's disk fills up: posts are refused with 507 naming the cause, nothing is half-written,
readiness says so, and once space returns posts are accepted again without a restart."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings
from tests.faults.test_crashes import caught_up
from tests.support.live_server import LiveServer

pytestmark = pytest.mark.processes  # mounts a small disk

EX = "https://example.org/full/"


def turtle(tag: str, triples: int) -> str:
    return "".join(f'<{EX}{tag}/s{n}> <{EX}p> "{tag} value {n} {"x" * 200}" .\n' for n in range(triples))


@contextlib.contextmanager
def small_disk(path: Path, megabytes: int) -> Iterator[Path]:
    """A tmpfs of its own, so filling it fills no one else's disk."""
    path.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={megabytes}m", "tmpfs", str(path)], capture_output=True, text=True
    )
    if mounted.returncode != 0:
        pytest.fail(f"cannot mount a tmpfs here (this test needs root): {mounted.stderr.strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def fill(disk: Path, leave_bytes: int) -> Path:
    filler = disk / "filler"
    free = shutil.disk_usage(disk).free
    with filler.open("wb", buffering=0) as output:
        output.truncate(0)
        block = b"\0" * (1 << 20)
        remaining = max(0, free - leave_bytes)
        try:
            while remaining > 0:
                written = output.write(block[: min(len(block), remaining)])
                remaining -= written
            output.flush()
            os.fsync(output.fileno())
        except OSError as error:  # the server wrote meanwhile: the disk is full sooner, which is the point
            if error.errno != errno.ENOSPC:
                raise
    return filler


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root; CI runs as root")
def test_a_full_disk_refuses_posts_with_507_and_recovers_without_a_restart(tmp_path: Path) -> None:
    with small_disk(tmp_path / "disk", 96) as disk:
        settings = make_settings(store="oxigraph", data_dir=disk / "data")
        with LiveServer(create_app(settings)) as server:
            assert httpx.post(f"{server.url}/ttl", content=turtle("before", 50), headers=NT).status_code == 201
            caught_up(server.url)  # the views' writes done, so the filler alone decides what is left
            filler = fill(disk, leave_bytes=64 * 1024)

            refused = [httpx.post(f"{server.url}/ttl", content=turtle(f"full{n}", 2000), headers=NT) for n in range(5)]
            full = [answer for answer in refused if answer.status_code == 507]
            assert full, [answer.status_code for answer in refused]
            assert "disk" in full[0].json()["detail"] and full[0].headers["retry-after"]
            assert set(answer.status_code for answer in refused) <= {201, 503, 507}
            ready = httpx.get(f"{server.url}/healthz/ready")
            assert ready.status_code == 503 and ready.json()["journal"] is False

            # Nothing half-written: a refused post has no receipt and none of its triples reach the store.
            receipts = httpx.get(f"{server.url}/ledger", params={"limit": 1000}).json()["receipts"]
            assert all(receipt["triples_received"] in (50, 2000) for receipt in receipts)
            refused_tags = [f"full{n}" for n, answer in enumerate(refused) if answer.status_code == 507]

            filler.unlink()  # space returns; no restart
            caught_up(server.url)
            assert httpx.get(f"{server.url}/healthz/ready").status_code == 200
            again = httpx.post(f"{server.url}/ttl", content=turtle("after", 50), headers=NT)
            assert again.status_code == 201
            stored = httpx.get(f"{server.url}/events", params={"format": "ntriples"}).text
            assert f"{EX}after/s0" in stored and f"{EX}before/s0" in stored
            assert not any(f"{EX}{tag}/" in stored for tag in refused_tags)
            assert httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}).json()["valid"] is True


def test_the_journal_quota_refuses_posts_past_it_with_507(tmp_path: Path) -> None:
    settings = make_settings(store="oxigraph", data_dir=tmp_path, journal_max_bytes=96 * 1024)
    with LiveServer(create_app(settings)) as server:
        statuses = [
            httpx.post(f"{server.url}/ttl", content=turtle(f"q{n}", 300), headers=NT).status_code for n in range(30)
        ]
        assert 201 in statuses and statuses[-1] == 507
        first_refused = statuses.index(507)
        refused = httpx.post(f"{server.url}/ttl", content=turtle("last", 300), headers=NT)
        assert refused.status_code == 507 and "JOURNAL_MAX_BYTES" in refused.json()["detail"]
        receipts = httpx.get(f"{server.url}/ledger", params={"limit": 1000}).json()["total"]
        assert receipts == first_refused  # every refused post left no receipt
        stored = httpx.get(f"{server.url}/events", params={"format": "ntriples"}).text
        assert f"{EX}last/" not in stored and f"{EX}q{first_refused}/" not in stored


NT = {"Content-Type": "application/n-triples"}
