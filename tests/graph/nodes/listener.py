"""Test node: subscribes to String messages and reports what it got.

Prints JSON lines: ``{"event": "ready"}`` once subscribed, ``{"event": "first", "after_s": t}`` at the
first message (seconds since the subscription was created), and at exit ``{"event": "done",
"received": [...], "dropped_count": ..., ...}``. Exits after ``--count`` messages, after ``--idle``
seconds without one, or at ``--timeout``.
"""

import argparse
import json
import sys
import time

import dptpu.graph as rclpy
from dptpu.graph import DurabilityPolicy, QoSProfile, ReliabilityPolicy, String


def emit(**event):
    print(json.dumps(event), flush=True)


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", default="listener")
    parser.add_argument("--topic", default="chatter")
    parser.add_argument("--count", type=int, default=0, help="exit after this many messages (0: no limit)")
    parser.add_argument("--timeout", type=float, default=10.0)
    parser.add_argument("--idle", type=float, default=0.0, help="exit after this many seconds without a message")
    parser.add_argument("--sleep", type=float, default=0.0, help="seconds each callback sleeps")
    parser.add_argument("--depth", type=int, default=10)
    parser.add_argument("--best-effort", action="store_true")
    parser.add_argument("--transient-local", action="store_true")
    parser.add_argument("--linger", type=float, default=0.0, help="seconds to stay alive after 'done'")
    parser.add_argument("--raise-on", default=None, help="the callback raises ZeroDivisionError on this text")
    options = parser.parse_args(rclpy.remove_ros_args(argv)[1:])
    rclpy.init(args=argv)
    node = rclpy.create_node(options.name)
    qos = QoSProfile(depth=options.depth,
                     reliability=ReliabilityPolicy.BEST_EFFORT if options.best_effort else ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL if options.transient_local
                     else DurabilityPolicy.VOLATILE)
    received = []
    state = {"last": time.monotonic()}
    created = time.monotonic()

    def on_message(msg):
        if not received:
            emit(event="first", after_s=time.monotonic() - created, data=msg.data)
        received.append(msg.data)
        state["last"] = time.monotonic()
        if options.raise_on is not None and msg.data == options.raise_on:
            raise ZeroDivisionError(f"test callback failure on {msg.data!r}")
        if options.sleep:
            time.sleep(options.sleep)

    subscription = node.create_subscription(String, options.topic, on_message, qos)
    deadline = time.monotonic() + options.timeout
    try:
        emit(event="ready", topic=subscription.topic_name, node=node.get_fully_qualified_name())
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.02)
            if options.count and len(received) >= options.count:
                break
            if options.idle and received and time.monotonic() - state["last"] > options.idle:
                break
    except KeyboardInterrupt:
        pass
    emit(event="done", received=received, dropped_count=subscription.dropped_count,
         queue_dropped_count=subscription.queue_dropped_count, lost_count=subscription.lost_count,
         malformed_count=subscription.malformed_count, received_count=subscription.received_count,
         taken_count=subscription.taken_count, exception_count=subscription.exception_count)
    try:
        end = time.monotonic() + options.linger
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
    except KeyboardInterrupt:
        pass
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
