"""Socket leases: a spinning executor receives from its nodes' SUB sockets itself; the I/O thread takes
them back for long callbacks, node moves and closes; the I/O thread sleeps between its deadlines."""

from __future__ import annotations

import threading
import time

from dptpu.graph import MultiThreadedExecutor, Node, SingleThreadedExecutor, String
from dptpu.graph.lease import IO, TAKEOVER_S
from dptpu.graph.qos import QoSProfile


def _spin_until(executor, condition, timeout_s: float = 3.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return condition()


def _pub_sub(context, name: str, callback, depth: int = 10):
    node = Node(name, context=context)
    subscription = node.create_subscription(String, "chatter", callback, QoSProfile(depth=depth))
    publisher = node.create_publisher(String, "chatter", depth)
    assert publisher.wait_for_subscriptions(1, timeout_sec=3.0)
    return node, subscription, publisher


def test_spinning_executor_receives_on_its_own_thread_through_the_lease(context):
    seen = []  # (data, thread, whether the socket was lent to the executor while its callback ran)
    executor = SingleThreadedExecutor(context=context)

    def on_message(msg):
        lease = executor._lease
        lent = lease is not None and lease.state != IO and subscription._socket in lease.subscriptions
        seen.append((msg.data, threading.get_ident(), lent))

    node, subscription, publisher = _pub_sub(context, "leased", on_message)
    executor.add_node(node)
    for index in range(20):
        publisher.publish(String(data=str(index)))
        assert _spin_until(executor, lambda expected=index + 1: len(seen) == expected)
    assert [data for data, _, _ in seen] == [str(i) for i in range(20)]
    assert {ident for _, ident, _ in seen} == {threading.get_ident()}
    assert sum(lent for _, _, lent in seen) >= 10  # typically all but the first, received before the grant
    assert subscription.received_count == subscription.taken_count == 20 and subscription.dropped_count == 0


def test_long_callback_lets_the_io_thread_drain_so_the_queue_drops_its_oldest(context):
    got = []

    def slow(msg):
        got.append(msg.data)
        if msg.data == "0":
            time.sleep(20 * TAKEOVER_S)  # 0.2 s: the I/O thread takes the sockets back meanwhile

    node, subscription, publisher = _pub_sub(context, "slow", slow, depth=3)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    publisher.publish(String(data="0"))
    assert _spin_until(executor, lambda: got == ["0"])
    started = threading.Event()

    def publish_during_callback():
        started.wait(2.0)
        for index in range(1, 31):
            publisher.publish(String(data=str(index)))
            time.sleep(0.002)

    thread = threading.Thread(target=publish_during_callback)
    thread.start()
    started.set()
    thread.join()
    # every message in the queue before the executor takes one (under load the I/O thread may still be receiving
    # the last ones when the publishing thread is done: the executor would take 27 before 30 arrived)
    deadline = time.monotonic() + 10.0
    while subscription.received_count < 31 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert subscription.received_count == 31
    assert _spin_until(executor, lambda: got[-1:] == ["30"])
    # 30 messages reached a queue of 3 while the callback slept: the oldest were dropped, none lost
    assert got[1:] == ["28", "29", "30"]
    assert subscription.queue_dropped_count == 27 and subscription.lost_count == 0
    assert subscription.taken_count + subscription.dropped_count == 31


def test_node_moved_to_another_executor_keeps_receiving(context):
    got = []
    node, _subscription, publisher = _pub_sub(context, "mover", lambda msg: got.append(msg.data))
    first, second = SingleThreadedExecutor(context=context), MultiThreadedExecutor(2, context=context)
    try:
        first.add_node(node)
        publisher.publish(String(data="a"))
        assert _spin_until(first, lambda: got == ["a"])
        second.add_node(node)  # leaves `first`, whose lease still holds the socket until it is taken back
        publisher.publish(String(data="b"))
        assert _spin_until(second, lambda: got == ["a", "b"])
        publisher.publish(String(data="c"))
        assert _spin_until(second, lambda: got == ["a", "b", "c"])
    finally:
        second.shutdown()


def test_idle_io_thread_wakes_only_for_its_deadlines(context):
    node = Node("quiet", context=context)
    node.create_subscription(String, "chatter", lambda msg: None, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.spin_once(timeout_sec=0.2)
    runtime = context._runtime()
    wakes = []
    poll = runtime._poller.poll

    def counting_poll(timeout=None):
        wakes.append(timeout)
        return poll(timeout)

    runtime._poller.poll = counting_poll
    try:
        _spin_until(executor, lambda: False, timeout_s=1.0)
    finally:
        runtime._poller.poll = poll
    # one second: 10 discovery scans, 1 statistics pass, a few lease checks; no polls with a zero timeout
    assert len(wakes) <= 20, wakes
    assert 0 not in wakes[1:], wakes
