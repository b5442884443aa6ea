"""Watching a topic from the CLI's node: ``echo`` (decoded messages) and ``hz``/``bw`` (raw frames, a report a
period).

Both look the topic up first (waiting up to ``wait_s`` for it to appear), subscribe with a QoS that connects to
every publisher (:func:`~.cli_node.subscription_qos`) and spin until done or until ``timeout_s`` has passed; what
is printed is the caller's (the callbacks).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from .cli_names import topic_message_class
from .cli_node import cli_node, subscription_qos
from .graph_view import find_topic

__all__ = ["spin_until", "echo_topic", "measure_topic", "REPORT_PERIOD_S", "MEASURE_QOS_DEPTH"]

#: Seconds between two ``hz`` / ``bw`` reports (as ros2).
REPORT_PERIOD_S = 1.0
#: Subscription queue depth of ``hz`` / ``bw``.
MEASURE_QOS_DEPTH = 100


def spin_until(executor, done: Callable[[], bool], deadline: float | None) -> bool:
    """Spin until ``done()``; False when ``deadline`` (monotonic s, or None) passed first."""
    while not done():
        if deadline is None:
            executor.spin_once(timeout_sec=0.5)
            continue
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        executor.spin_once(timeout_sec=remaining)
    return True


def _deadline(timeout_s: float | None) -> float | None:
    return None if timeout_s is None else time.monotonic() + timeout_s


def echo_topic(topic: str, domain_id: int, on_message: Callable, *, wait_s: float, depth: int = 10,
               limit: int | None = None, timeout_s: float | None = None) -> int:
    """Call ``on_message(msg)`` for each message of ``topic`` (at most ``limit``); return how many came.

    Parameters
    ----------
    topic : str
        Absolute topic name; its type must be one this build knows (``ValueError`` otherwise).
    domain_id : int
    on_message : callable
        Called with each decoded message, in the executor's thread.
    wait_s : float
        Seconds to wait for the topic to appear (:class:`~.graph_view.UnknownNameError` after).
    depth : int
        Subscription queue depth.
    limit : int, optional
        Stop after this many messages (default: until ``timeout_s``, or forever).
    timeout_s : float, optional
        Stop after this many seconds (default: never).
    """
    info = find_topic(topic, domain_id, wait_s=wait_s)
    msg_type = topic_message_class(info, required=True)
    qos = subscription_qos([p.qos for p in info.publishers], depth=depth)
    delivered = [0]

    def deliver(msg) -> None:
        if limit is not None and delivered[0] >= limit:
            return
        on_message(msg)
        delivered[0] += 1

    deadline = _deadline(timeout_s)
    with cli_node(domain_id) as (node, executor):
        node.create_subscription(msg_type, topic, deliver, qos)
        spin_until(executor, lambda: limit is not None and delivered[0] >= limit, deadline)
    return delivered[0]


def measure_topic(topic: str, domain_id: int, on_frames: Callable, report: Callable[[], bool], *, wait_s: float,
                  timeout_s: float | None = None, on_subscribed: Callable[[], None] | None = None) -> int:
    """Subscribe raw to ``topic``, call ``on_frames(frames)`` per message and ``report()`` every
    :data:`REPORT_PERIOD_S`; return how many reports said they had something (``report()`` true).

    The topic's type need not be known: the frames are counted, not decoded. ``on_subscribed()`` is called once
    the subscription exists. Runs until ``timeout_s`` (default: forever, i.e. until Ctrl-C).
    """
    info = find_topic(topic, domain_id, wait_s=wait_s)
    msg_type = topic_message_class(info, required=False)
    qos = subscription_qos([p.qos for p in info.publishers], depth=MEASURE_QOS_DEPTH)
    deadline = _deadline(timeout_s)
    reports = 0
    with cli_node(domain_id) as (node, executor):
        node.create_subscription(msg_type, topic, on_frames, qos, raw=True)
        if on_subscribed is not None:
            on_subscribed()
        next_report = time.monotonic() + REPORT_PERIOD_S
        while True:
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                break
            until = next_report if deadline is None else min(next_report, deadline)
            executor.spin_once(timeout_sec=max(0.0, until - now))
            if time.monotonic() >= next_report:
                next_report += REPORT_PERIOD_S
                reports += bool(report())
    return reports
