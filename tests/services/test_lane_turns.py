"""Which view's lane updates next when the general turns are taken: the reports before the other views (their lag is
what readiness and the ingest's pace watch), then the cheapest batch, then the first come; a small batch takes the
express turn beside them."""

from __future__ import annotations

import threading
import time

from segb_server.backend.services.views.turns import Turns, served_first


def _queue(turns: Turns, waiters: list[tuple[str, float, bool, bool]]) -> list[str]:
    """The order in which `waiters` (name, cost, small, first), all waiting while the one general turn is taken,
    get a turn."""
    order: list[str] = []
    lock = threading.Lock()
    hold = threading.Event()

    def wait(name: str, cost: float, small: bool, first: bool) -> None:
        with turns.turn(cost, small=small, first=first):
            with lock:
                order.append(name)
            time.sleep(0.02)

    def holder() -> None:
        with turns.turn(0.0, small=False):
            hold.wait(10)

    threads = [threading.Thread(target=holder)]
    threads[0].start()
    time.sleep(0.05)
    for waiter in waiters:
        threads.append(threading.Thread(target=wait, args=waiter))
        threads[-1].start()
        time.sleep(0.02)  # arrival order as listed
    hold.set()
    for thread in threads:
        thread.join(10)
    return order


def test_a_report_takes_the_general_turn_before_a_cheaper_view_of_another_kind() -> None:
    order = _queue(
        Turns(general=1, express=0),
        [
            ("graph", 1.0, False, False),
            ("timeline/message", 0.1, False, False),
            ("reports/conversations", 5.0, False, True),
        ],
    )
    assert order == ["reports/conversations", "timeline/message", "graph"]


def test_among_reports_the_cheapest_first_and_a_small_batch_takes_the_express_turn() -> None:
    order = _queue(
        Turns(general=1, express=1),
        [("reports/participants", 3.0, False, True), ("reports/conversations", 1.0, False, True),
         ("timeline/message", 0.0, True, False)],
    )  # fmt: skip
    assert order[0] == "timeline/message"  # small: the express turn, free all along
    assert order[1:] == ["reports/conversations", "reports/participants"]


def test_the_reports_are_the_views_served_first() -> None:
    assert served_first("reports/conversations") and served_first("reports/participants")
    assert not any(served_first(name) for name in ("graph", "shape-findings", "timeline/message", "rules/late-answer"))
