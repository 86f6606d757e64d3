"""The cursor the applier and the views' keeper move through the journal, and that posts and readers wait on."""

from __future__ import annotations

import threading

from segb_server.backend.services.writing.cursor import Cursor


def test_advancing_never_goes_back_and_setting_may() -> None:
    cursor = Cursor()
    cursor.advance(5)
    cursor.advance(3)  # a late report of an earlier step
    assert cursor.value == 5
    cursor.set(2)  # a store found restored is applied again from its own cursor
    assert cursor.value == 2


def test_a_wait_ends_when_another_thread_moves_the_cursor_there() -> None:
    cursor = Cursor()
    mover = threading.Timer(0.01, cursor.advance, args=(4,))
    mover.start()
    assert cursor.wait_for(4, timeout=10)
    mover.join()
    assert cursor.wait_for(3, timeout=0)  # already past: at once


def test_a_wait_past_its_time_says_so() -> None:
    assert not Cursor().wait_for(1, timeout=0.01)


def test_a_wait_needs_its_condition_too() -> None:
    cursor = Cursor()
    cursor.advance(2)
    ready = threading.Event()
    threading.Timer(0.01, lambda: (ready.set(), cursor.advance(2))).start()  # moving wakes the waiter to check
    assert cursor.wait_for(2, timeout=10, reached=ready.is_set)
    assert not cursor.wait_for(2, timeout=0.01, reached=lambda: False)


def test_a_follower_polls_for_progress_made_by_another_process() -> None:
    """No thread of this process moves the cursor: the poll reads the leader's progress (the store's cursor)."""
    cursor = Cursor()
    polls: list[int] = []

    def poll() -> None:
        polls.append(cursor.value)
        if len(polls) == 3:
            cursor.advance(7)

    assert cursor.wait_for(7, timeout=10, poll=poll, poll_seconds=0.001)
    assert polls == [0, 0, 0]
