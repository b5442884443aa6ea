"""A slow subscriber never stalls the publisher or a fast subscriber; it drops the OLDEST and counts it."""

from __future__ import annotations

N = 200


def test_slow_subscriber_drops_oldest_and_counts_while_fast_one_gets_all(spawn):
    slow = spawn("listener", "--name", "slow", "--sleep", "0.05", "--depth", "5", "--idle", "0.6", "--timeout", "15")
    fast = spawn("listener", "--name", "fast", "--depth", "1000", "--count", str(N), "--timeout", "15")
    slow.wait_event("ready")
    fast.wait_event("ready")
    talker = spawn("talker", "--count", str(N), "--period", "0.002", "--wait-subs", "2", "--linger", "0.2")
    assert talker.wait_event("published")["count"] == N

    fast_done = fast.wait_event("done")
    assert fast_done["received"] == [str(i) for i in range(N)]
    assert fast_done["dropped_count"] == 0

    slow_done = slow.wait_event("done")
    taken = slow_done["received"]
    # every message is accounted for: handed to the callback, or dropped (oldest-first from its queue)
    assert len(taken) + slow_done["dropped_count"] == N
    assert slow_done["dropped_count"] == slow_done["queue_dropped_count"] + slow_done["lost_count"]
    assert slow_done["dropped_count"] > N // 2  # 50 ms per callback against 2 ms per message
    # dropping the oldest keeps the newest: the last message published is the last one processed
    assert taken[-1] == str(N - 1)
    values = [int(v) for v in taken]
    assert values == sorted(values)
