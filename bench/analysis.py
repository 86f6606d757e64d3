"""The explanatory sections of docs/performance.md: where a post's time goes, Virtuoso's floor, memory."""

from __future__ import annotations

from bench.measure import Latency
from bench.runs import ManyRobots, SmallPosts
from bench.virtuoso import Floor


def _rows(header: list[str], rows: list[list[str]]) -> list[str]:
    return [
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---" if i == 0 else "--:" for i in range(len(header))) + "|",
        *("| " + " | ".join(row) + " |" for row in rows),
        "",
    ]


def breakdown_section(steps: dict[str, Latency], embedded: SmallPosts | None, floor: SmallPosts | None) -> list[str]:
    """The embedded small post split into the ingest steps (timed in-process) and what HTTP costs around them."""
    if not steps or embedded is None or floor is None:
        return []
    rest = embedded.latency.p50 - floor.latency.p50 - sum(latency.p50 for latency in steps.values())
    rows = [[step, f"{latency.p50:.3f}", f"{latency.mean:.3f}"] for step, latency in steps.items()]
    rows += [
        ["uvicorn, FastAPI routing and dependencies, thread hop, logging (the rest)", f"{rest:.3f}", ""],
        ["client, loopback, HTTP parsing (no-op server)", f"{floor.latency.p50:.3f}", f"{floor.latency.mean:.3f}"],
        ["**end to end (embedded row above)**", f"{embedded.latency.p50:.3f}", f"{embedded.latency.mean:.3f}"],
    ]
    return [
        "**Where an embedded small post's time goes.** The ingest steps are timed in-process on the same payloads",
        "(bench/breakdown.py, fresh on-disk store and ledger); the rest is the p50 difference. The store write",
        "is RocksDB's transaction for ~50 quads (about 6 µs per quad, three indexes each, growing slowly with",
        "the store); the receipt is one SQLite WAL commit (synchronous=NORMAL). Profiling the server with",
        "py-spy showed the remainder spread thinly over Starlette middleware, FastAPI's dependency solving",
        "(~0.15 ms for this route), the hop to the worker thread, and the two INFO log lines per post (the",
        "request line and the ingest line, each to stderr and the JSON server log): the `LOGGING_LEVEL=WARNING`",
        "row above is the same server without them.",
        "",
        *_rows(["step", "p50 ms", "mean ms"], rows),
    ]


def robots_section(embedded: ManyRobots | None, floor: ManyRobots | None) -> list[str]:
    """Why concurrent robots on the embedded store stop where they do."""
    if embedded is None or floor is None:
        return []
    return [
        "*stored* is counted from each server's own export (GET /events as N-Triples); the baseline has no",
        "export, so its graph is counted in Virtuoso directly.",
        "",
        f"**Why 16 robots stop near {embedded.posts_per_second:.0f} posts/s on the embedded store.**",
        "Both cores are busy: the 16 client threads take about one (the no-op row is what they and HTTP",
        "alone reach), the server the other. One Python process owns the embedded store, and only one of",
        "its threads runs Python at a time. Profiled with py-spy under this load, the event-loop thread",
        "(uvicorn's HTTP, Starlette middleware, FastAPI routing and dependencies, the response and the",
        "request log line) holds more than half of the server's busy samples; the worker threads parsing and",
        "writing hold the rest. Group commit (backend/services/group_commit.py) has concurrent posts share",
        "one writer pass and one ledger transaction, so no post queues on a lock and one SQLite commit serves",
        "many receipts, but it cannot remove the per-request work. 1,000 posts/s would leave about 1 ms of",
        "one core per post for all of it, while a trivial FastAPI route of this server already costs about",
        "half of that and RocksDB's write of ~50 quads another third. It would take more cores, or several",
        "API processes in front of one store process (the embedded store allows one owner), or an ingest",
        "path outside the per-request framework.",
        "",
    ]


def virtuoso_floor_section(floor: Floor, ours: SmallPosts, naive: SmallPosts) -> list[str]:
    """Why 5x the naive baseline on Virtuoso cannot hold while a post is acknowledged after Virtuoso commits."""
    target = naive.latency.p50 / 5
    rows = [
        ["`ASK {}` (one round trip, digest auth)", "0", *_cells(floor.ask)],
        ["`INSERT DATA` (the baseline's update)", f"{floor.triples_per_insert:.0f}", *_cells(floor.insert_data)],
        ["conditional `INSERT … FILTER NOT EXISTS` (ours)", f"{floor.triples_per_insert:.0f}",
         *_cells(floor.conditional_insert)],
        ["SEGB post on Virtuoso, end to end", f"{ours.triples_per_post:.0f}", *_cells(ours.latency)],
        ["naive baseline post, end to end", f"{naive.triples_per_post:.0f}", *_cells(naive.latency)],
    ]  # fmt: skip
    return [
        "### Virtuoso's floor, and what 5x the baseline would take",
        "",
        "Bare requests to the same Virtuoso, without any server in front (bench/virtuoso.py), on fresh triples:",
        "",
        *_rows(["request", "triples", "p50 ms", "p95 ms", "p99 ms"], rows),
        f"Five times the baseline's p50 would be {target:.1f} ms per post, while a single update of one post's",
        f"triples costs Virtuoso {floor.insert_data.p50:.1f} ms (`INSERT DATA`) or "
        f"{floor.conditional_insert.p50:.1f} ms (conditional) before any server adds its own work. Both the",
        "baseline and this server are that update plus a little: as long as a post is answered only after",
        "Virtuoso has committed its triples, the ratio is bounded by (baseline) / (Virtuoso's update), about",
        f"{naive.latency.p50 / max(floor.insert_data.p50, 1e-9):.1f}x here, whatever the server does.",
        "",
        "What it would take: acknowledge a post once it is in a durable local write-ahead journal (an",
        "append-only SQLite or RocksDB log on the server, committed with the ledger receipt) and flush the",
        "journal to Virtuoso in the background, many posts per conditional insert. A small post would then",
        "cost about what it costs on the embedded store. The price: `triples_new` would have to be computed",
        "against the journal and the known-triples memory instead of Virtuoso's answer; reads would lag writes",
        "by the flush delay unless queries wait for the journal to drain; the journal must be replayed after a",
        "crash and must stop accepting (503) when Virtuoso stays down and the journal fills; and the server",
        "becomes the only safe writer of the graph. That design is not built.",
        "",
        "Concurrent robots on Virtuoso go through the same group commit (one ledger transaction per batch),",
        "but each post still costs one conditional insert: `triples_new` per post comes from Virtuoso's count",
        "for that post's update. Merging a batch into one update needs the store to say which triples were",
        "missing (a `SELECT` over the batch's `VALUES`, then one `INSERT DATA`: two round trips per batch",
        "instead of one per post), a change to the store adapter's interface.",
        "",
    ]


def memory_section(peak_rss_mib: dict[tuple[str, int], float | None]) -> list[str]:
    """Peak resident memory (VmHWM) of the processes, read after each report-size step."""
    rows = [[process, f"{size:,}", f"{rss:.0f}"] for (process, size), rss in peak_rss_mib.items() if rss]
    if not rows:
        return []
    return [
        "### Memory",
        "",
        "Peak resident set size (Linux `VmHWM`) after loading and querying each report dataset. Each embedded",
        "size is a fresh API process; Virtuoso is one process for the whole run.",
        "",
        *_rows(["process", "triples", "peak RSS MiB"], rows),
    ]


def _cells(latency: Latency) -> list[str]:
    return [f"{latency.p50:.1f}", f"{latency.p95:.1f}", f"{latency.p99:.1f}"]
