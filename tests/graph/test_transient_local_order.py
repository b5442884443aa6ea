"""TRANSIENT_LOCAL: a late subscriber gets the replay of the last message BEFORE any live message.

The publisher is a real process publishing as fast as it can; the late subscribers are bare ZeroMQ SUB sockets of
this process (what a subscription opens), which show each message's envelope: a subscriber must see the replay
(HISTORY flag) first and then the live messages from the next sequence number on, without a gap.
Without ``XPUB_MANUAL`` the publisher's socket could apply a newcomer's subscription inside the ``send`` of a
live message, after the publisher had looked for newcomers: the live message then arrived first and the
subscription dropped the replay as already seen (measured at full publishing rate before the fix: 16 and 36 of
400 joins; 0 after).
"""
from __future__ import annotations

import zmq

from dptpu.graph.transport import FLAG_HISTORY, unpack_envelope

JOINS = 250


def _first_messages(endpoint: str, topic: bytes, count: int, timeout_ms: int = 5000) -> list:
    """The envelopes of the first ``count`` messages a fresh SUB socket receives from ``endpoint``."""
    sock = zmq.Context.instance().socket(zmq.SUB)
    try:
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.SUBSCRIBE, topic)
        sock.connect(endpoint)
        envelopes = []
        for _ in range(count):
            assert sock.poll(timeout_ms), f"no message from {endpoint} within {timeout_ms} ms"
            frames = sock.recv_multipart()
            envelopes.append(unpack_envelope(frames[-1]))
        return envelopes
    finally:
        sock.close(linger=0)


def test_late_subscriber_gets_the_replay_before_any_live_message(spawn):
    talker = spawn("talker", "--count", "2000000", "--depth", "1", "--transient-local", "--linger", "0")
    ready = talker.wait_event("ready")
    endpoint = next(e for e in ready["endpoints"] if e.startswith("ipc://"))
    topic = ready["topic"].encode()
    _first_messages(endpoint, topic, 1)  # publishing has begun: from now on there is a message to replay
    inverted = []
    for join in range(JOINS):
        first, second, third = _first_messages(endpoint, topic, 3)
        if not first.flags & FLAG_HISTORY:
            inverted.append((join, first.seq))
            continue
        # after the replay of the last message, live messages follow from the next sequence number on
        assert not second.flags & FLAG_HISTORY and not third.flags & FLAG_HISTORY
        assert (second.seq, third.seq) == (first.seq + 1, first.seq + 2), (join, first, second, third)
    assert inverted == [], f"{len(inverted)} of {JOINS} late subscribers got a live message first: {inverted[:5]}"
