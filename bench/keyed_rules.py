"""What each kept view's query costs for one batch's keys, as the views' upkeep asks it, at a long history.

    python -m bench.keyed_rules                          # 2,000 visits of one robot, the last 100 as the batch
    python -m bench.keyed_rules --visits 4000 --repeat 9
    python -m bench.keyed_rules --sparql-dir /tmp/old/sparql --rules-dir /tmp/old/rules   # another version's files

A batch's upkeep evaluates each view's query again for the keys the batch touched (`VALUES ?key { … }` opening
its WHERE group, parameters unbound: `kept_text`). That evaluation is most of a view's CPU a post, and how the
rules of reading (backend/reading.py) are written decides it: an OPTIONAL whose body is two patterns is evaluated
once in full by the embedded store, so its cost grows with the log, where one pattern or one path is evaluated
for each row with the row's values bound.

The history is one robot's visits (bench/one_robot.py) in an embedded store in memory; the keys are each view's
keys among the subjects of the last 100 visits. Printed: the median and p95 of `--repeat` evaluations, the keys
and rows, and the total. With `--sparql-dir` and `--rules-dir` pointing at another version's `.rq` files (e.g.
`git archive a94935a sparql rules | tar -x -C /tmp/old`), the same run measures those, expanded by this
version's rules of reading where they call one.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from pyoxigraph import RdfFormat, Store

from bench.measure import machine, percentile
from bench.one_robot import one_robot
from segb_server.backend.services.sparql.catalog import Catalog, CatalogQuery
from segb_server.backend.services.views.kept_queries.plan import declared_key, plan_report
from segb_server.backend.services.views.kept_queries.plan_parts import Unsupported
from segb_server.backend.services.views.kept_queries.projection import kept_text
from segb_server.backend.store.terms import bind_texts

ROOT = Path(__file__).resolve().parent.parent
BATCH_VISITS = 100


def _kept(directory: Path) -> list[CatalogQuery]:
    queries = []
    for query in Catalog(directory):
        try:
            if declared_key(query):
                queries.append(query)
        except Unsupported:
            continue
    return queries


def _subjects(ntriples: str) -> set[str]:
    return {line.split(" ", 1)[0] for line in ntriples.splitlines() if line.startswith("<")}


def measure(store: Store, query: CatalogQuery, batch_subjects: set[str], repeat: int) -> tuple[list[float], int, int]:
    """The keyed evaluation's times in seconds, the keys and the rows of one evaluation."""
    plan = plan_report(query)
    unit = plan.unit()
    text = kept_text(query, plan)
    keys = sorted(
        {
            str(solution[unit])
            for solution in store.query(text)
            if solution[unit] is not None and str(solution[unit]) in batch_subjects
        }
    )
    if not keys:
        return [], 0, 0
    keyed = bind_texts(text, [unit], [[key] for key in keys], wrap=False)
    seconds, rows = [], 0
    for _ in range(repeat):
        start = time.perf_counter()
        rows = sum(1 for _ in store.query(keyed))
        seconds.append(time.perf_counter() - start)
    return seconds, len(keys), rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--visits", type=int, default=2000, help="visits of history, the last 100 the batch")
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--sparql-dir", type=Path, default=ROOT / "sparql")
    parser.add_argument("--rules-dir", type=Path, default=ROOT / "rules")
    args = parser.parse_args()

    robot = one_robot()
    store = Store()
    store.load((robot.first + robot.history(args.visits)).encode(), RdfFormat.N_TRIPLES)
    batch = _subjects(robot.history(BATCH_VISITS, args.visits - BATCH_VISITS))
    print(
        f"`python -m bench.keyed_rules --visits {args.visits}`: {len(store):,} triples; each kept view's query for "
        f"the keys of the last {BATCH_VISITS} visits ({args.sparql_dir}, {args.rules_dir})\n"
    )
    print("| view | keys | rows | p50 ms | p95 ms |\n|---|--:|--:|--:|--:|")
    total = 0.0
    queries = [*_kept(args.sparql_dir), *_kept(args.rules_dir)]
    for query in queries:
        name = query.name if (args.sparql_dir / f"{query.name}.rq").exists() else f"rules/{query.name}"
        seconds, keys, rows = measure(store, query, batch, args.repeat)
        if not seconds:
            print(f"| {name} | 0 | | | |")
            continue
        median = statistics.median(seconds) * 1000
        total += median
        print(f"| {name} | {keys} | {rows} | {median:.2f} | {percentile(seconds, 95) * 1000:.2f} |")
    per_visit = total / BATCH_VISITS
    print(f"\nevery view, p50 summed: {total:.1f} ms a batch of {BATCH_VISITS} visits ({per_visit:.2f} ms a visit)")
    print("machine: " + "; ".join(f"{key} {value}" for key, value in machine().items()))


if __name__ == "__main__":
    main()
