"""TRANSIENT_LOCAL: a late subscription gets the publisher's last ``depth`` messages; a VOLATILE one does not."""

from __future__ import annotations


def test_transient_local_delivers_last_messages_to_late_subscriber(spawn):
    talker = spawn("talker", "--count", "3", "--depth", "2", "--transient-local", "--linger", "10")
    assert talker.wait_event("published")["count"] == 3
    late = spawn("listener", "--transient-local", "--depth", "5", "--idle", "0.5", "--timeout", "5")
    done = late.wait_event("done")
    assert done["received"] == ["1", "2"]  # the last depth=2 of 0, 1, 2; in order, no duplicates


def test_volatile_late_subscriber_gets_no_history(spawn):
    talker = spawn("talker", "--count", "3", "--depth", "2", "--transient-local", "--linger", "10")
    assert talker.wait_event("published")["count"] == 3
    volatile = spawn("listener", "--timeout", "1.0")
    assert volatile.wait_event("done")["received"] == []


def test_transient_local_subscription_is_not_matched_with_volatile_publisher(spawn):
    # ROS 2 rule: requesting TRANSIENT_LOCAL from a VOLATILE publisher is incompatible (warned, not connected)
    # the talker outlives the listener (10 s) even when a loaded machine starts the listener slowly
    talker = spawn("talker", "--count", "2000", "--period", "0.005", "--linger", "0")
    talker.wait_event("ready")
    listener = spawn("listener", "--transient-local", "--timeout", "1.0")
    assert listener.wait_event("done")["received"] == []
    assert listener.wait_for_stderr("requests TRANSIENT_LOCAL but the publisher offers VOLATILE", timeout=2.0)


def test_late_transient_local_subscriber_gets_history_then_live_without_gap_or_duplicate(spawn):
    # 2000 messages (10 s): the listener gets its 30 even when a loaded machine starts it slowly
    talker = spawn("talker", "--count", "2000", "--period", "0.005", "--depth", "5", "--transient-local",
                   "--linger", "0")
    talker.wait_event("ready")
    listener = spawn("listener", "--transient-local", "--depth", "50", "--count", "30")
    done = listener.wait_event("done")
    values = [int(v) for v in done["received"]]
    assert values == list(range(values[0], values[0] + 30))
    assert done["lost_count"] == 0 and done["dropped_count"] == 0
