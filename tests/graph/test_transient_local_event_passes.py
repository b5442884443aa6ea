"""The I/O thread's passes over a TRANSIENT_LOCAL publisher's subscribe events: fast for a while after the graph
changed (a newcomer connects within a few discovery scans), slow once it is still; a newcomer still gets the
replay at once."""

from __future__ import annotations

import time

from dptpu.graph import DurabilityPolicy, Node, QoSProfile, SingleThreadedExecutor, String
from dptpu.graph import runtime as graph_runtime

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _passes_in(calls: list, seconds: float) -> int:
    calls.clear()
    time.sleep(seconds)
    return len(calls)


def test_event_passes_slow_down_in_a_still_graph_and_a_newcomer_gets_the_replay(context, monkeypatch):
    monkeypatch.setattr(graph_runtime, "EVENTS_HOT_S", 0.5)
    node = Node("latcher", context=context)
    publisher = node.create_publisher(String, "/latched", LATCHED)
    publisher.publish(String(data="kept"))
    calls: list[float] = []
    service_events = publisher._service_events

    def counted() -> None:
        calls.append(time.monotonic())
        service_events()

    monkeypatch.setattr(publisher, "_service_events", counted)  # what the I/O thread calls each pass
    time.sleep(1.5)  # the start-up's hot window is over
    still = _passes_in(calls, 2.0)
    # every 250 ms and the once-a-second counter pass: ~10 in 2 s (80 at the 25 ms of a changing graph)
    assert 4 <= still <= 20, still

    monkeypatch.setattr(graph_runtime, "EVENTS_HOT_S", 5.0)  # read at each change of the graph
    received: list[str] = []
    late = Node("late_joiner", context=context)  # a new entity: the graph changed
    late.create_subscription(String, "/latched", lambda msg: received.append(msg.data), LATCHED)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(late)
    deadline = time.monotonic() + 10.0
    while not received and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert received == ["kept"]
    hot = _passes_in(calls, 1.0)  # inside the hot window the change opened: every 25 ms
    assert hot >= still + 4, (hot, still)  # 40 a second unloaded; slow passes would give the same as still
    executor.shutdown()
