"""The explanatory paragraphs of docs/performance.md: where a post's time goes, what the lag and the journal's
size mean, Virtuoso's floor, memory. Figures in them come from the run; the reasoning is written here."""

from __future__ import annotations

import textwrap

from bench.breakdown import MAINTENANCE, STEPS
from bench.crosscheck import UNCHECKED, check_of
from bench.freshness import SteadyLag
from bench.live import LiveReports
from bench.measure import Latency
from bench.runs import ManyRobots, SmallPosts
from bench.tables import table
from bench.virtuoso import Floor

MACHINE_NOTE = [
    "The machine's 2 cores are shared with other work, and the clients run on them too: every figure is from",
    "one modest run (a few hundred to a few thousand requests per row), not a tuned or isolated one. Treat",
    "differences of a few tenths of a millisecond as noise. Whole runs differ more: on 2026-11-24 three runs of",
    "section 1 on the same code put the embedded small post's p50 at 3.4, 4.6 and 6.5 ms, and the in-process",
    "steps of its breakdown moved together by up to 2x (a virtual machine whose neighbours vary). Compare rows",
    "of one run with each other, not with another run's. Machines differ more still: on 2026-11-25 the runs",
    "from 16:10 UTC were on a fresh machine (an Intel Xeon) about twice as fast as the one before (with the same",
    "ingest code, 16 robots on the embedded store reached 187 posts/s there and 98 before), and the runs on this",
    "page, from 21:00 UTC, on another (an AMD EPYC) about as fast as that Xeon (its 1M import: 53 s against 56).",
    "",
    "The bench's own garbage collector is off while it measures (each server's start collects): its full",
    "collections grew with the answers it had read, to a second by the end of a reports run, and a pause",
    "counted in whichever request was in flight. Runs before 2026-11-25 07:20 UTC include such pauses: in one",
    "of them, a post's rows seemed to need 1.2 s to reach their report, all of it the bench's collection.",
]

REFERENCE_NOTE = [
    "The reference backend itself cannot run here (it is not installed and nothing can be fetched), so the",
    "naive baseline stands in for it: the same steps in the same run, against the same Virtuoso.",
    "",
]


def client_floor_note(floor: SmallPosts) -> list[str]:
    return [
        "The no-op server answers at once (bench/null_server.py, same uvicorn HTTP parser and loop): its",
        f"{floor.latency.p50:.2f} ms p50 is the client's own time plus loopback and HTTP, included in every row",
        "above. The bench client is the standard library's `http.client`; httpx costs about 0.5 ms more",
        "per request.",
        "",
    ]


def breakdown_section(steps: dict[str, Latency], embedded: SmallPosts | None, floor: SmallPosts | None) -> list[str]:
    """The embedded small post split into the ingest steps (timed in-process) and what HTTP costs around them."""
    if not steps or embedded is None or floor is None:
        return []
    on_path = {step: latency for step, latency in steps.items() if not step.startswith(MAINTENANCE)}
    rest = embedded.latency.p50 - floor.latency.p50 - sum(latency.p50 for latency in on_path.values())
    rows = [[step, f"{latency.p50:.3f}", f"{latency.mean:.3f}"] for step, latency in on_path.items()]
    rows += [
        ["uvicorn, FastAPI, thread hops, logging, and waiting for the cores (the rest)", f"{rest:.3f}", ""],
        ["client, loopback, HTTP parsing (no-op server)", f"{floor.latency.p50:.3f}", f"{floor.latency.mean:.3f}"],
        ["**end to end (embedded row above)**", f"{embedded.latency.p50:.3f}", f"{embedded.latency.mean:.3f}"],
    ]
    for step, after in steps.items():
        if step.startswith(MAINTENANCE):
            rows.append([f"*{step}*", f"{after.p50:.3f}", f"{after.mean:.3f}"])
    lines = [
        "**Where an embedded small post's time goes.** The ingest steps are timed in-process on the same payloads",
        "(bench/breakdown.py, fresh on-disk journal and store, one post at a time as `INGEST_ACK=store` does on the",
        "embedded store); the rest is the p50 difference. The journal append is one SQLite WAL transaction",
        "(synchronous=NORMAL) holding the receipt, the post's new triples compressed, and their digests; the",
        "applier reads the entry back, parses it and writes its quads and the applied cursor in one RocksDB",
        "transaction.",
        "",
        *table(["step", "p50 ms", "mean ms"], rows),
    ]
    if MAINTENANCE in steps:
        upkeep = steps[MAINTENANCE].p50
        path = sum(latency.p50 for latency in on_path.values())
        lines += [
            "The last row is not on the post's path: after each applied step the reports' thread looks up the",
            "rows the new triples can change and evaluates each report again for those keys. For one small post",
            f"that is {upkeep:.0f} ms, {upkeep / max(path, 1e-9):.0f} times the post's own in-process work, in the",
            "same process: the thread competes with the next requests for the interpreter and the 2 cores, so a",
            "sequence of posts pays for it in *the rest*. Profiled with py-spy while 600 small posts ran one after",
            "another (12 s at 200 Hz), the reports' thread was busy about three quarters of the time, more than",
            "the event loop and the posting threads together. The row kept current with only the participants",
            "report (the same server given a copy of `sparql/` with the other report files left out) shows what",
            "the other five cost the posts.",
            "",
        ]
        edges = [latency for step, latency in steps.items() if step.startswith(MAINTENANCE) and step != MAINTENANCE]
        if len(edges) == 2:
            lines += [
                f"It grows with what the store holds: {edges[0].p50:.0f} ms per post over the first posts, "
                f"{edges[1].p50:.0f} ms over the",
                "last ones, for posts of the same size from the same robot.",
                "",
            ]
    return lines


def robots_notes(embedded: ManyRobots | None, floor: ManyRobots | None) -> list[str]:
    """Why concurrent robots on the embedded store stop where they do."""
    if embedded is None or floor is None:
        return []
    drain = embedded.lag.drain.reports_seconds if embedded.lag else None
    return [
        "*stored* is counted through each server's own `/sparql` (`COUNT`) once the store and the reports had",
        "caught up; the baseline has no SPARQL route, so its graph is counted in Virtuoso directly.",
        "",
        f"**Why 16 robots stop near {embedded.posts_per_second:.0f} posts/s on the embedded store.** Both cores",
        "are busy: the 16 client threads take a large share of one (the no-op row is what they and HTTP alone",
        "reach), the server the rest. One Python process owns the embedded store, and only one of its threads",
        "runs Python at a time: the event loop (HTTP, middleware, routing, the response and the request log",
        "line), the posting threads (parsing, the journal entry, applying), and the thread keeping the reports",
        "current all share it. The store itself keeps up (`apply_lag` stays within a few entries); the reports'",
        "rows fall behind by hundreds of entries and catch up only after the load"
        + (f" ({drain:.1f} s here)." if drain is not None else "."),
        "",
    ]


WORKERS_LABEL = "API worker"  # in the names of the "workers" section's rows
POSTGRES_LABEL = "PostgreSQL state"  # in the names of its rows with the state in PostgreSQL


def workers_notes(robots: dict[str, ManyRobots]) -> list[str]:
    """What more API processes bought on this machine, from the rows of the "workers" section."""
    rows = {name: run for name, run in robots.items() if WORKERS_LABEL in name}
    if len(rows) < 2:
        return []
    best_name, best = max(rows.items(), key=lambda item: item[1].posts_per_second)
    one = next(iter(rows.values()))
    gain = best.posts_per_second / one.posts_per_second if one.posts_per_second else 0.0
    limit = (
        "more workers mostly move the queue from one place to another"
        if gain < 1.3
        else "the gain stays well short of the number of workers"
    )
    text = (
        f"**API workers on Virtuoso** (`API_WORKERS`, the rows *{'*, *'.join(rows)}*): the best was *{best_name}* "
        f"at {best.posts_per_second:.0f} posts/s (p99 {best.latency.p99:,.0f} ms), against "
        f"{one.posts_per_second:.0f} posts/s (p99 {one.latency.p99:,.0f} ms) for one process ({gain:.1f}x). This "
        f"machine has 2 cores, and the 16 client threads, Virtuoso and every worker share them, so {limit}: "
        "Virtuoso's own CPU per post (the applier's writes and the views' queries) is the limit here, as the "
        "capacity model in docs/scaling.md shows. Each row is one run, and whole runs differ by up to a factor of "
        "2 here."
    )
    shared = {name: run for name, run in rows.items() if POSTGRES_LABEL in name}
    if shared:
        rates = ", ".join(f"{run.posts_per_second:.0f}" for run in shared.values())
        text += (
            f" With the state in PostgreSQL (`STATE_URL`, the rows ending *{POSTGRES_LABEL}*: {rates} posts/s) a "
            "fourth server shares the same 2 cores, and every append is a round trip to it; it runs here without "
            "fsync, as the tests' fixture starts it. PostgreSQL is there for several hosts, not for speed on one."
        )
    return [*textwrap.wrap(text, 110, break_on_hyphens=False), ""]


def steady_notes(steady: dict[str, SteadyLag]) -> list[str]:
    if not steady:
        return []
    return [
        "On the embedded store the applier writes a post within milliseconds of its 201 (*in store*); a reader of",
        "`/sparql` waits longer because a query there runs in a worker process over a snapshot taken when the",
        "data changed since the last one (a RocksDB checkpoint opened by the worker): at 10 posts/s nearly",
        "every ASK pays for a fresh snapshot. On Virtuoso `/resource` is two queries with labels, so *in store* is",
        "the slower reader there; the ASK is one round trip.",
        "",
    ]


JOURNAL_SIZE_NOTE = [
    "The journal keeps each triple once (an entry holds only what the journal did not hold yet, zlib-compressed)",
    "plus a 16-byte digest per triple in an indexed table and one receipt per post; a re-publish that adds",
    "nothing costs a receipt. So it grows with the unique triples, not with what the robot re-sends. Most of",
    "the size right after a run is the `-wal` file: SQLite copies it into the database at each checkpoint",
    "(every 1,000 pages by default) and then reuses it, so it stays near 4 MB whatever the journal's size.",
    "",
]

LIVE_INTRO = [
    "The store is loaded with `segb import` of generated N-Triples (copies of one emotion-mirror robot's 100",
    "interactions, each copy with its own robot, visitor and days) before the server starts; on Virtuoso the",
    "import runs with `INGEST_ACK=store`, so it applies what it journals and the server starts on a loaded",
    "store. The server then builds the reports' rows and the graph index in the background (until they are",
    "built, reports are answered by their queries and `/graph` by a 503); the measurements start once every",
    "view is built (*every view built s*). While the pages are measured, one more robot publishes its events at 10",
    "posts/s, and a second client follows the conversations report as a live `/reports` page does: when",
    "the report's live stream (`/reports/stream`) names a post's messages, it reads",
    "`/reports/conversations?robot=…&since=…` (again every 20 ms until they are rows; a check that falls behind",
    "is skipped, not timed late). The time is from the post's 201 to that page holding its messages. Filters",
    "come from the data: the first participant pair, and a one-day window from the first message's time.",
    "Each row of the pages table is the same request repeated; default page size 1,000 rows.",
    "",
    "Before the pages are measured, the robot's conversations are watched the whole way, in a real page:",
    "the web UI (`segb serve --only ui`) serves `/reports/conversations?robot=…` to headless Chromium with live",
    "updates on, and a script in the page notes when each message first shows (its bubble's explain link). The",
    "time is from a post's 201 to the last of its messages showing, for every post with messages answered while",
    "the page was watched (*open page in Chromium*): the views, the API's stream, the UI's relay, the page's",
    "script fetching its rows again, and the browser drawing them.",
]


def live_notes(live: dict[tuple[str, int], LiveReports]) -> list[str]:
    built = [
        f"{store} at {size:,}: " + ", ".join(f"{name} {keys:,} keys in {seconds:.1f} s"
                                             for name, (keys, seconds) in sorted(item.built.items()))
        for (store, size), item in live.items()
        if item.built
    ]  # fmt: skip
    lines = ["Each report's build at start-up, as the server logged it:", "", *(f"* {line}" for line in built), ""]
    return (
        (lines if built else [])
        + _wrong_pages(live)
        + [
            "**How a post reaches the pages.** Pages are read from the reports' rows, and the graph views from the",
            "graph index; both follow the store through the views thread, which takes the applied steps in",
            "batches. Per batch each report costs about two bound queries (the keys the new triples touch, found",
            "from each triple's subject, asked as one UNION; then the report again for those keys), the reports and",
            "the graph index are updated side by side, and the thread then rests as long as the batch took, so",
            "under a steady stream it uses at most half of the time and of the store's. An aggregate report's",
            "unfiltered pages read its kept groups. A filtered page is chosen from its filter's index, which holds",
            "the sort key, and reads only its own rows. A preset (`# same-as:`, the extreme emotions) is served",
            "from its base's rows. *rows visible after 201* and *max reports_lag entries* above",
            "say whether it kept up with the robot. All of it is derived from each report's `.rq` file: a new",
            "report declares only its row key (`# key: ?message`; for an aggregate, its groups) and its filters",
            "(`# param`), and is kept the same way without any Python (docs/reports.md, *How reports stay fast*).",
            "",
            "**The graph views and explanations are read from the graph index**",
            "(`backend/services/views/graph_index.py`): a first view or a neighbourhood is a few indexed SQLite",
            "queries whatever the size of the log; a label search or a time window scans the index's nodes. The",
            "first view, the one each visit opens with, is kept until a change reaches what it draws (new",
            "activities sort after its last node), so under a stream of posts it is mostly answered as kept. It is",
            "drawn when the index is built or a server starts with it and, while it was asked for in the last two",
            "minutes, drawn again by the",
            "views' keeper as soon as a step changes it; a request meanwhile gets the view before, with the",
            "`through` that view includes, and a live page fetches the new one when the stream tells it. A",
            "neighbourhood (`focus`) is kept until a step writes a node within its depth (the index logs the nodes",
            "each step writes): another robot's posts leave it kept, its own robot's draw it again (the two",
            "`focus` rows above). An",
            "explanation walks the index's links and reads the few literals a story tells (texts, labels, model",
            "versions, intensities, confidences), which the index keeps whole. The steps the store has applied and",
            "the index not yet (a post just answered) are read from the journal and added to what the index tells,",
            "so an explanation asked right after a 201 tells that post. Only while a clearing is on its way to the",
            "index, or more than 100 steps are, does it read the store, as it always did on Virtuoso (about ten",
            "round trips, 160 ms at p50 at a million triples under live ingest).",
            "The big answers (a first view of 1,500 nodes is 0.9 to 1.3 MB) are encoded with orjson, and a",
            "report's rows are stored as orjson writes them and read back with it (1,000 rows: 1.4 ms, 4.7 with json).",
            "",
            "On Virtuoso the p95s are about twice the embedded store's for the same pages, though neither store",
            "is asked: Virtuoso answers the views' upkeep queries on the same 2 cores as the server, the robot and",
            "the auditor, and a request that meets such a moment waits for a core. Most of that upkeep is Virtuoso",
            "planning each query again, since every batch binds new keys into the text (section 1, *Virtuoso's",
            "floor*); its SPARQL endpoint cannot be handed the keys beside a text that stays the same (a URL",
            "parameter named after a `?:` variable left the variable unbound when tried). What brought the tails",
            "under the bounds is work taken off those cores: a preset is kept once with its base (the extreme",
            "emotions had doubled the emotion timeline's upkeep), the first view is drawn by the keeper rather",
            "than by a waiting request, a filtered page sorts its index's keys rather than its rows, and the",
            "robot's checker follows the live stream as a page does instead of asking for the conversations 50",
            "times a second, which had been a load of its own.",
            "",
            "A post's rows at a million triples on Virtuoso wait for the batch under way, the rest after it and",
            "their own batch. On the machine of earlier runs (2026-11-24 and 25, about half as fast: its 1M import",
            "took 109 s against 56 s on the Xeon after it) each was about a quarter of a second, and the slowest of",
            "about 60 posts took 0.7 to 1.2 s over five runs at 2eb9e9f to 076c557. On the twice faster machines",
            "since, a batch takes about 0.14 s (traced: 135 ms p50, 170 ms p95), and five runs at 389b60c, 81a210c,",
            "0ae015e, fce57d0 and f95782e (the last on this page) put the p99 at 0.54, 0.56, 0.48, 0.54 and 0.53 s.",
            "Since 3be2a1e a rest no longer keeps a step waiting more than 0.4 s since it was applied, which bounds",
            "that wait on a slower machine; with one or two busy cores taken from the Xeon, batches grew to 0.18 and",
            "0.21 s and the p99 stayed within 0.6 to 0.75 s with the bound and without it (one run each: run to run",
            "noise).",
            "",
            "Tried and left out: handing Virtuoso a batch's keys in a graph of their own instead of VALUES, so a",
            "report's text, and so its plan, stays the same. Alone, the conversations report for three keys took 7",
            "ms instead of 28 (the emotion timeline needed its `|` path written as a UNION, or took 500 ms). Under",
            "live ingest the writes of the keys, one per report and batch beside the applier's, made the batches",
            "slower (135 to 260 ms p50, 894 ms p95), so VALUES stayed.",
            "",
        ]
    )


def _wrong_pages(live: dict[tuple[str, int], LiveReports]) -> list[str]:
    """Empty filtered pages whose report's query, run through `/sparql` with the same filter, has rows."""
    wrong = [
        f"{store} at {size:,}: `{page.report}` with {page.variant} served 0 rows from its rows; its query answers "
        f"{check_of(page)}"
        for (store, size), item in live.items()
        for page in item.pages
        if check_of(page) not in (None, 0, UNCHECKED)
    ]
    if not wrong:
        return []
    return [
        "**Pages that disagree with their query.** Every filtered page that came back empty was checked against",
        "the report's own query (`sparql/reports/*.rq`) run through `/sparql` with the same filter bound:",
        "",
        *(f"* {line}." for line in wrong),
        "",
        "Those pages are wrong answers, whatever their latency.",
        "",
    ]


def virtuoso_floor_section(floor: Floor, store_ack: SmallPosts, journal_ack: SmallPosts | None,
                           naive: SmallPosts) -> list[str]:  # fmt: skip
    """Why acknowledging after Virtuoso's commit is bounded by Virtuoso's own update time."""
    rows = [
        ["`ASK {}` (one round trip, digest auth)", "0", *_cells(floor.ask)],
        ["`INSERT DATA` (the baseline's update)", f"{floor.triples_per_insert:.0f}", *_cells(floor.insert_data)],
        ["conditional `INSERT … FILTER NOT EXISTS`", f"{floor.triples_per_insert:.0f}",
         *_cells(floor.conditional_insert)],
        ["SEGB post, `INGEST_ACK=store`, end to end", f"{store_ack.triples_per_post:.0f}", *_cells(store_ack.latency)],
        *([["SEGB post, `INGEST_ACK=journal`, end to end", f"{journal_ack.triples_per_post:.0f}",
            *_cells(journal_ack.latency)]] if journal_ack else []),
        ["naive baseline post, end to end", f"{naive.triples_per_post:.0f}", *_cells(naive.latency)],
        *([["the conversations report for one new message (a text not seen before)", "0",
            *_cells(floor.report_new_key)],
           ["the same query asked again (its plan kept)", "0", *_cells(floor.report_same_key)]]
          if floor.report_new_key and floor.report_same_key else []),
    ]  # fmt: skip
    return [
        "### Virtuoso's floor",
        "",
        "Bare requests to the same Virtuoso, without any server in front (bench/virtuoso.py), on fresh triples:",
        "",
        *table(["request", "triples", "p50 ms", "p95 ms", "p99 ms"], rows),
        "A post answered only after Virtuoso committed it (`INGEST_ACK=store`) costs at least one update, so",
        f"against the baseline it is bounded by (baseline) / (Virtuoso's update): about "
        f"{naive.latency.p50 / max(floor.insert_data.p50, 1e-9):.1f}x here, whatever the server does.",
        "With `INGEST_ACK=journal` a post is answered once its entry is in the local journal, and the applier",
        "writes many posts per update in the background; the post's latency no longer includes Virtuoso at all.",
        "",
        "`INGEST_ACK=store` costs more than the baseline here because a post arriving alone is applied as a",
        "step of its own: an `INSERT DATA` of its triples and then a second update moving the applied cursor",
        "(`DELETE WHERE … ; INSERT DATA …` in the cursor's graph), on top of the journal's own commit; the baseline",
        "makes one update. Under concurrent posts the steps hold many posts and the cursor's update is shared.",
        "",
        *(_planning_note(floor) if floor.report_new_key and floor.report_same_key else []),
    ]


def _planning_note(floor: Floor) -> list[str]:
    """What keeping the reports current costs Virtuoso: planning each new query text again."""
    assert floor.report_new_key is not None and floor.report_same_key is not None
    planning = floor.report_new_key.p50 - floor.report_same_key.p50
    return [
        "The last two rows are what keeping the reports current asks of Virtuoso after each batch of posts: each",
        "report's query bound to the keys the batch touched. Every such text is new to Virtuoso, which plans it",
        f"again: about {planning:.0f} ms of its CPU per query here (new text p50 minus the same text's), on top of",
        f"a round trip that costs {floor.ask.p50:.1f} ms even for `ASK {{}}`. A batch asks one to four such queries",
        "of each of the six reports; the views' thread rests after each batch, but while a",
        "batch runs Virtuoso takes both cores, and requests served from the views' own rows wait for one",
        "(section 5's Virtuoso p95s).",
        "",
    ]


def journal_ack_note(
    steps: dict[str, Latency], floor: SmallPosts | None, journal_ack: SmallPosts | None, naive: SmallPosts
) -> list[str]:
    """What 5x the baseline would ask of a post acknowledged from the journal."""
    if not steps or floor is None or journal_ack is None:
        return []
    own = [latency.p50 for step, latency in steps.items() if step in STEPS[:4]]  # up to the journal's commit
    path = sum(own) + floor.latency.p50
    return [
        f"Five times the baseline's p50 is {naive.latency.p50 / 5:.1f} ms. A post acknowledged from the journal",
        f"still decodes, parses, journals and crosses HTTP: {path:.1f} ms at p50 by the in-process steps of",
        f"section 1 and the no-op server, against {journal_ack.latency.p50:.1f} ms measured end to end. The",
        "difference is the framework around the route and the server's other threads (the applier writing to",
        "Virtuoso, the reports' thread querying it) taking turns with the posting thread on 2 cores.",
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
        "Peak resident set size (Linux `VmHWM`) after loading, building the reports' rows and measuring under",
        "live ingest. Each API process is fresh per size; Virtuoso is one process for the whole run.",
        "",
        *table(["process", "triples", "peak RSS MiB"], rows),
    ]


def _cells(latency: Latency) -> list[str]:
    return [f"{latency.p50:.1f}", f"{latency.p95:.1f}", f"{latency.p99:.1f}"]
