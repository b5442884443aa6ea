"""Sequence numbers a stranger cannot poison (``dptpu.graph.sequence_tracking``), and the per-publisher table's
bound. The in-process rules here; ``test_forged_messages_processes.py`` sends the forged message over real sockets."""

from __future__ import annotations

import tracemalloc

import pytest

from dptpu.graph.sequence_tracking import MAX_COUNTED_GAP, REPLAY_WINDOW, SequenceTracker

SIM = b"s" * 16


def _feed(tracker: SequenceTracker, seqs, *, gid: bytes = SIM, history: bool = False) -> list:
    return [tracker.accept(gid, seq, history=history) for seq in seqs]


def test_forged_sequence_two_to_the_62_does_not_stop_later_real_messages():
    tracker = SequenceTracker()
    _feed(tracker, range(1, 11))
    forged = tracker.accept(SIM, 2**62)
    later = _feed(tracker, range(11, 111))
    assert forged.deliver
    assert all(v.deliver for v in later)  # before: all 100 dropped as "already delivered"
    assert sum(v.lost for v in later) == 0  # the foreign jump counts no loss
    assert "foreign or forged" in later[0].note
    assert tracker.last(SIM) == 110


def test_two_forged_messages_confirming_a_jump_still_do_not_stop_the_real_publisher():
    tracker = SequenceTracker()
    _feed(tracker, range(1, 6))
    _feed(tracker, (2**62, 2**62 + 1))
    later = _feed(tracker, range(6, 56))
    assert all(v.deliver for v in later)
    assert "went back" in later[0].note
    assert all(not v.note for v in later[1:])


def test_small_gaps_are_counted_at_once_and_a_confirmed_large_jump_when_confirmed():
    tracker = SequenceTracker()
    verdicts = _feed(tracker, (1, 2, 5, 6))
    assert [v.lost for v in verdicts] == [0, 0, 2, 0]
    big = 6 + MAX_COUNTED_GAP + 10
    assert tracker.accept(SIM, big).lost == 0  # provisional
    confirmed = tracker.accept(SIM, big + 1)
    assert confirmed.lost == big - 6 - 1 and not confirmed.note


def test_replays_within_the_window_are_repeats_and_a_restarted_numbering_is_delivered():
    tracker = SequenceTracker()
    _feed(tracker, range(1, 21))
    assert not any(v.deliver for v in _feed(tracker, range(11, 21), history=True))
    assert all(v.deliver for v in _feed(tracker, (21, 22), history=True))
    tracker2 = SequenceTracker()
    tracker2.accept(SIM, REPLAY_WINDOW + 100)
    restarted = tracker2.accept(SIM, 5, history=True)
    assert restarted.deliver and "went back" in restarted.note


def test_live_message_below_the_last_is_delivered_never_dropped():
    tracker = SequenceTracker()
    _feed(tracker, range(1, 50))
    verdict = tracker.accept(SIM, 3)
    assert verdict.deliver and verdict.lost == 0 and "went back" in verdict.note


def test_table_is_bounded_and_its_memory_flat_over_20k_new_publisher_ids():
    tracker = SequenceTracker(max_publishers=256)
    _feed(tracker, range(1, 4))
    tracemalloc.start()
    try:
        for index in range(1000):  # fill to the bound first
            tracker.accept(index.to_bytes(16, "little"), 1)
        before, _ = tracemalloc.get_traced_memory()
        for index in range(1000, 21_000):
            tracker.accept(index.to_bytes(16, "little"), 1)
        after, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(tracker) == 256
    assert after - before < 64 * 1024, after - before  # before the bound: +17 MB per 100k ids, 3.4 MB here
    assert tracker.last(SIM) is None  # the least recently heard went first


def test_forget_and_bad_bound():
    tracker = SequenceTracker()
    tracker.accept(SIM, 7)
    tracker.forget(SIM)
    assert tracker.last(SIM) is None and len(tracker) == 0
    with pytest.raises(ValueError, match="max_publishers must be >= 1"):
        SequenceTracker(max_publishers=0)
