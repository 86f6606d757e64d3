"""The interpreter's garbage collector, tuned for the server's long-running processes (`segb serve`).

Python's cycle collector runs a young collection every 700 allocations and, now and then, a full one that walks
every object the process holds (the catalog, the views' plans, the caches of terms): in the views' process it took
about a third of their CPU (a batch of 75 visits of one robot: 5.97 ms a visit, 4.16 with the collector off). What
start-up made lives as long as the process: frozen, it is never walked again; and young collections every 10,000
allocations keep garbage cycles (a traceback's frames) as short-lived as they need to be.
"""

from __future__ import annotations

import gc

YOUNG_COLLECTION_EVERY = 10_000  # allocations (Python's default: 700)


def tune_collector() -> None:
    """Freeze what the process made so far, and collect young objects less often."""
    gc.freeze()
    gc.set_threshold(YOUNG_COLLECTION_EVERY, *gc.get_threshold()[1:])
