"""Executors, timers, callback groups, futures, in one process."""

from __future__ import annotations

import threading
import time

from dptpu.graph import (
    MultiThreadedExecutor,
    MutuallyExclusiveCallbackGroup,
    Node,
    ReentrantCallbackGroup,
    SingleThreadedExecutor,
    String,
    Trigger,
)
from dptpu.graph.task import Future


def test_timer_fires_at_its_period_and_cancel_stops_it(context):
    node = Node("ticker", context=context)
    ticks = []
    timer = node.create_timer(0.02, lambda: ticks.append(time.monotonic()))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + 0.3
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert 10 <= len(ticks) <= 16  # 0.3 s / 0.02 s = 15 periods (skipped periods are never replayed)
    gaps = [b - a for a, b in zip(ticks, ticks[1:])]
    assert min(gaps) > 0.01
    timer.cancel()
    count = len(ticks)
    executor.spin_once(timeout_sec=0.1)
    assert len(ticks) == count and timer.is_canceled()


def test_exception_in_timer_is_counted_and_spin_goes_on(context):
    node = Node("faulty", context=context)
    calls = []

    def tick():
        calls.append(1)
        raise RuntimeError("boom")

    timer = node.create_timer(0.01, tick)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    for _ in range(3):
        executor.spin_once(timeout_sec=0.5)
    assert len(calls) == 3 and timer.exception_count == 3


def _run_group_experiment(context, group_factory):
    node = Node("grouped", context=context)
    group = group_factory()
    active, peak, lock = [0], [0], threading.Lock()

    def slow():
        with lock:
            active[0] += 1
            peak[0] = max(peak[0], active[0])
        time.sleep(0.05)
        with lock:
            active[0] -= 1

    for _ in range(3):
        node.create_timer(0.01, slow, callback_group=group)
    executor = MultiThreadedExecutor(num_threads=3, context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    time.sleep(0.3)
    executor.shutdown()
    thread.join(2.0)
    node.destroy_node()
    return peak[0]


def test_reentrant_group_overlaps_and_mutually_exclusive_group_does_not(context):
    assert _run_group_experiment(context, MutuallyExclusiveCallbackGroup) == 1
    assert _run_group_experiment(context, ReentrantCallbackGroup) >= 2


def test_client_call_inside_a_callback_does_not_deadlock(context):
    server = Node("server", context=context)
    server.create_service(Trigger, "ping", lambda req, resp: Trigger.Response(success=True, message="pong"))
    caller = Node("caller", context=context)
    client = caller.create_client(Trigger, "ping")
    answers = []
    caller.create_subscription(String, "go", lambda m: answers.append(client.call(Trigger.Request(), 2.0).message), 10)
    publisher = caller.create_publisher(String, "go", 10)
    executor = MultiThreadedExecutor(num_threads=2, context=context)  # the server needs a thread of its own
    executor.add_node(server)
    executor.add_node(caller)
    assert client.wait_for_service(3.0) and publisher.wait_for_subscriptions(1, 3.0)
    publisher.publish(String(data="now"))
    deadline = time.monotonic() + 3.0
    while not answers and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert answers == ["pong"]
    executor.shutdown()


def test_spin_until_future_complete_and_tasks(context):
    node = Node("futures", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    future = Future(executor=executor)
    node.create_timer(0.02, lambda: future.done() or future.set_result(42))
    done_values = []
    future.add_done_callback(lambda f: done_values.append(f.result()))
    executor.spin_until_future_complete(future, timeout_sec=2.0)
    assert future.result() == 42
    task = executor.create_task(lambda a, b: a * b, 6, 7)
    executor.spin_until_future_complete(task, timeout_sec=1.0)
    executor.spin_once(timeout_sec=0.1)
    assert task.result() == 42 and done_values == [42]


def test_shutdown_makes_spin_return(graph_env):
    from dptpu.graph import Context

    ctx = Context()
    ctx.init()
    node = Node("short_lived", context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    time.sleep(0.05)
    ctx.shutdown()
    thread.join(2.0)
    assert not thread.is_alive() and not ctx.ok()
